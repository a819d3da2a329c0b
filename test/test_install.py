"""Every verb of the command line, run from the package as users install it — a wheel in a fresh
venv, and a plain ``colcon build`` — with the working directory outside the source tree. A
package, data file or entry point missing from an install fails here (the source tree and the
editable install would hide it)."""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
from pathlib import Path

import pytest

from installs import ROOT, Install
from procs import end_all

pytestmark = pytest.mark.process


@pytest.fixture(params=["wheel", "colcon"])
def install(request) -> Install:
    return request.getfixturevalue(
        f"{request.param}_installed" if request.param == "wheel" else "colcon_built"
    )


def call(inst: Install, cwd: Path, *args: str, timeout: float = 180, domain: int | None = None):
    """``predictive-drive ARGS`` from the install, in ``cwd``; the completed process."""
    env = dict(inst.env)
    if domain is not None:
        env["ROS_DOMAIN_ID"] = str(domain)
    return subprocess.run(
        [*inst.cli, *args], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout
    )


def ok_json(inst: Install, cwd: Path, *args: str, **kw) -> dict:
    r = call(inst, cwd, *args, "--json", **kw)
    assert r.returncode == 0, f"{' '.join(args)}: exit {r.returncode}\n{r.stderr[-3000:]}"
    return json.loads(r.stdout)


def test_the_installed_package_is_the_one_running(install, tmp_path):
    """Not the checkout: the imported package and its data come from the install."""
    code = (
        "import predictive_drive, predictive_drive.reports.papers as p; "
        "from predictive_drive.config import config_dir; "
        "print(predictive_drive.__file__); print(config_dir())"
    )
    r = subprocess.run(
        [str(install.python), "-c", code], cwd=tmp_path, env=install.env, capture_output=True,
        text=True, timeout=60,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    module, config = r.stdout.split()
    assert Path(module).is_relative_to(install.prefix), module
    assert not Path(module).is_relative_to(ROOT / "src")
    assert Path(config).is_relative_to(install.prefix), config


def test_every_verb_runs_from_the_install(install, tmp_path):
    from predictive_drive.ros.processes import isolated_domain

    work = tmp_path / "work"  # a user's own folder: no config/, no package.xml
    work.mkdir()
    r = call(install, work, "--help")
    assert r.returncode == 0 and "run" in r.stdout and "``" not in r.stdout, r.stdout
    assert call(install, work, "--version").stdout.startswith("predictive-drive ")

    # run: each engine
    runs = {}
    for engine in ("inprocess", "composed", "ros"):
        # the node processes with losses on: the device file comes from the install's share
        losses = ["--set", "plant.losses.device=semikron_skm150gb124d"] if engine == "ros" else []
        out = ok_json(install, work, "run", "im_short", "--engine", engine, "--duration", "0.1",
                      "--out", f"bags/{engine}", *losses)  # fmt: skip
        assert out["steps"] == 2000 and out["engine"] == engine
        assert 0 < out["metrics"]["t_rmse"] < 10
        runs[engine] = out
    assert (work / "bags" / "ros" / "logs" / "plant.log").is_file()
    assert runs["ros"]["metrics"]["p_inverter"] > 0 and runs["ros"]["device"] == "SKM 150 GB 124 D"

    # report, with the figures (matplotlib from the `figures` extra)
    rep = ok_json(install, work, "report", "bags/ros", "--figures", "figures")
    assert rep["metrics"]["t_rmse"] == runs["ros"]["metrics"]["t_rmse"]
    assert rep["metrics"]["p_inverter"] == runs["ros"]["metrics"]["p_inverter"]
    assert rep["figures"] and all(Path(work / f).is_file() for f in rep["figures"])

    cmp_ = ok_json(install, work, "compare", "bags/inprocess", "bags/composed")
    assert [r_["metrics"]["t_rmse"] for r_ in cmp_["runs"]] == [
        runs["inprocess"]["metrics"]["t_rmse"], runs["composed"]["metrics"]["t_rmse"]
    ]  # fmt: skip

    # analyze: a PMSM run with a torque threshold
    ok_json(install, work, "run", "spmsm_short", "--strategy", "simplified1", "--engine",
            "inprocess", "--duration", "0.1", "--out", "bags/pmsm")  # fmt: skip
    an = ok_json(install, work, "analyze", "bags/pmsm")
    assert an["steps"] > 0 and an["utilization"]["six_sector"]

    with isolated_domain() as domain:
        played = ok_json(install, work, "replay", "bags/inprocess", "--rate", "50",
                         "--topics", "/clock", domain=domain)  # fmt: skip
        assert played["published"] == {"/clock": 101}
        into = ok_json(install, work, "replay", "bags/inprocess", "--into", "torque_controller",
                       "--out", "bags/into")  # fmt: skip
        assert into["agreement"]["pulses"] == 1.0 and into["steps"] == 2000

        # param: a node started as `ros2 run` starts it, reached through its parameter services
        params = install.share() / "config" / "im_short.yaml"
        env = {**install.env, "ROS_DOMAIN_ID": str(domain)}
        node = subprocess.Popen(
            [*install.node("torque_controller"), "--ros-args", "--params-file", str(params)],
            cwd=work, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            start_new_session=True,
        )  # fmt: skip
        try:
            get = call(install, work, "param", "get", "torque_controller", "strategy",
                       domain=domain, timeout=60)  # fmt: skip
            assert get.returncode == 0 and get.stdout.strip() == "db_mptc", get.stderr
            set_ = call(install, work, "param", "set", "torque_controller", "strategy", "mptc",
                        domain=domain, timeout=60)  # fmt: skip
            assert set_.returncode == 0, set_.stderr
            again = call(install, work, "param", "get", "torque_controller", "strategy",
                         domain=domain, timeout=60)  # fmt: skip
            assert again.stdout.strip() == "mptc"
        finally:
            node.send_signal(signal.SIGINT)
            end_all([node])

    # repair: a copy of a bag cut in the middle, as a killed writer leaves it
    cut = work / "bags" / "cut"
    shutil.copytree(work / "bags" / "inprocess", cut)
    (mcap,) = cut.glob("*.mcap")
    mcap.rename(cut / "cut_0.mcap")
    (cut / "metadata.yaml").unlink()
    data = (cut / "cut_0.mcap").read_bytes()
    (cut / "cut_0.mcap").write_bytes(data[: len(data) // 2])
    fixed = ok_json(install, work, "repair", "bags/cut")
    assert fixed["repaired"] and 0 < fixed["steps"] < 2000
    assert ok_json(install, work, "report", "bags/cut")["steps"] == fixed["steps"]

    r = call(install, work, "layout", "--out", "drive.foxglove.json")
    assert r.returncode == 0, r.stderr
    assert json.loads((work / "drive.foxglove.json").read_text())["configById"]
    assert ok_json(install, work, "layout", "--out", "drive.foxglove.json", "--force")["replaced"]

    rep = ok_json(install, work, "reproduce", "im_paper", "--duration", "0.06")
    assert [r_["strategy"] for r_ in rep["rows"]] == ["mptc", "mptc_db", "db_mptc"]
    assert rep["bags"] is None and not list(work.glob("bags/reproduce_*"))  # none kept

    sw = ok_json(install, work, "sweep", "im_short", "--strategy", "mptc,db_mptc",
                 "--duration", "0.05")  # fmt: skip
    assert len(sw["rows"]) == 2 and not any(r_["error"] for r_ in sw["rows"])
    # drawn drives of the saturating machine (its scenario installed with the rest)
    sw = ok_json(install, work, "sweep", "pmsyrm_steady", "--strategy", "mptc,simplified1",
                 "--draw", "2", "--spread", "plant.motor.r_s=normal:0.1", "--duration", "0.02")  # fmt: skip
    assert len(sw["rows"]) == 4 and [d["strategy"] for d in sw["drawn"]] == ["mptc", "simplified1"]
    rob = ok_json(install, work, "reproduce", "robustness", "--points", "ipmsm_steady",
                  "--draws", "2", "--duration", "0.03")  # fmt: skip
    assert rob["draws"] == 2 and len(rob["points"][0]["figures"]) == 4
    eff = ok_json(install, work, "reproduce", "efficiency", "--speeds-rpm", "1000", "--torques",
                  "15", "--duration", "0.06")  # fmt: skip
    assert eff["runs"] == 3 and [len(m["efficiency"]) for m in eff["maps"]] == [1, 1, 1]

    bench = ok_json(install, work, "bench", "--quick", timeout=300)
    assert bench["core_steps_per_s"] > 0 and bench["report_steps_per_s"] > 0
    assert 0 < bench["losses"]["of_real"] < 2 and bench["losses"]["losses_steps_per_s"] > 0
    assert bench["losses"]["booking"] in ("compiled", "python")
    rows = [(h["strategy"], h["horizon"]) for h in bench["horizons"]]
    assert rows == [("mptc", n) for n in (1, 2, 3, 5)] + [("direct_mpc", n) for n in (1, 3, 5, 10)]
    assert all(h["of_core"] > 0 and h["of_core_near"] > 0 for h in bench["horizons"])

    # nothing was written into the source tree
    assert not (ROOT / "bags" / "inprocess").exists()


MISSING = (
    "import sys; sys.modules['mcap'] = None; from predictive_drive.cli import main; "
    "sys.exit(main(sys.argv[1:]))"
)


def test_a_missing_package_is_one_line_naming_it(install, tmp_path):
    """An install without one of its packages (a workspace built without rosdep): `--help` and
    a verb say which package and how to install it, in one line, without a traceback."""
    said = (
        "predictive-drive: error: the Python package mcap is not installed: pip install 'mcap'; "
        "in a ROS workspace, rosdep install --from-paths src --ignore-src -y (its key: "
        "mcap-ros2-support)"
    )
    for args in (["--help"], ["run", "--help"], ["report", "some_bag"]):
        r = subprocess.run(
            [str(install.python), "-c", MISSING, *args],
            cwd=tmp_path, env=install.env, capture_output=True, text=True, timeout=120,
        )  # fmt: skip
        assert r.returncode == 2 and r.stderr.splitlines() == [said], (args, r.stderr)
