from setuptools import setup

setup(
    name="dtc_im",
    version="0.1.0",
    packages=["dtc_im"],
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/dtc_im"]),
        ("share/dtc_im", ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    description="Switching-table DTC of an induction motor for predictive_drive's graph",
    license="Apache-2.0",
    entry_points={"console_scripts": ["dtc_node = dtc_im.dtc_node:main"]},
)
