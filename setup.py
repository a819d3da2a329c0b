"""ament_python package: `colcon build` installs the node executables into lib/predictive_drive."""

from pathlib import Path

from setuptools import find_packages, setup

PACKAGE = "predictive_drive"
NODES = ["plant_node", "speed_pi_node", "torque_controller_node", "metrics_logger_node"]

setup(
    name=PACKAGE,
    version="0.1.0",
    description="Model predictive torque control of electric drives on a lock-step ROS 2 graph",
    license="Apache-2.0",
    python_requires=">=3.11",  # enum.StrEnum
    package_dir={"": "src"},
    packages=find_packages("src"),
    package_data={
        f"{PACKAGE}.core.control": ["candidate_tables.json"],
        f"{PACKAGE}.ros": ["fastdds_profiles.xml"],
    },
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", sorted(str(p) for p in Path("config").glob("*.yaml"))),
        (f"share/{PACKAGE}/config/devices", sorted(str(p) for p in Path("config/devices").glob("*.json"))),
        (f"share/{PACKAGE}/launch", ["launch/drive.launch.xml"]),
        (f"share/{PACKAGE}/layouts", ["layouts/drive.foxglove.json"]),
    ],
    install_requires=[
        "numpy>=1.24,<3",
        "mcap>=1.1,<2",
        "PyYAML>=6,<7",
        "tqdm>=4.60,<5",
    ],
    extras_require={
        # what a ROS 2 Jazzy install already provides; the Makefile installs it from wheels
        "ros": ["ros-jazzy-rclpy[fastrtps]>=7.1,<8", "ros-jazzy-common-interfaces>=5.3,<6"],
        "figures": ["matplotlib>=3.8,<4"],
        # the live view (run --live): no rosdep key exists for it
        "live": ["foxglove-sdk>=0.30.3,<0.31"],
        # sweep: the Parquet table and Dask clusters (--scheduler)
        "sweep": ["pyarrow>=21,<27", "dask[distributed]>=2025.1,<2027"],
        # fast: the compiled kernels, direct_mpc's sphere decoder (core/control/kernels.py) and
        # the losses' booking (core/losses_kernel.py); about 210 MB
        "fast": ["numba>=0.60,<1"],
        "test": ["pytest>=8,<10", "pytest-xdist>=3.5,<4", "rosbags>=0.10,<0.12", "mcap-ros2-support>=0.5,<0.7",
                 "colcon-core>=0.17,<0.22", "colcon-ros>=0.5,<0.6",
                 "colcon-python-setup-py>=0.2.8,<0.3", "ruff>=0.6,<1", "mypy>=1.10,<3",
                 "types-PyYAML>=6,<7", "types-tqdm>=4.60,<5",
                 "websocket-client>=1.7,<2"],
    },
    zip_safe=False,  # the nodes hand Fast DDS the path of ros/fastdds_profiles.xml
    entry_points={
        "console_scripts": [
            "predictive-drive = predictive_drive.cli:main",
            *(f"{n} = predictive_drive.ros.{n}:main" for n in NODES),
        ],
    },
)
