"""Bad input and faults (issue: nothing lost, nothing false): every case ends with a clear error
naming the file, key or value, no traceback, nothing half-written presented as a good bag."""

from __future__ import annotations

import json
import os
import resource
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from predictive_drive.api.run import run, run_inprocess_to_bag
from predictive_drive.bag import LOGS_DIR
from predictive_drive.config import config_dir, load_scenario
from predictive_drive.errors import BagError, ConfigError
from predictive_drive.readback import read_bag

pytestmark = pytest.mark.core

CLI = [sys.executable, "-m", "predictive_drive.cli"]
SHORT = config_dir() / "im_short.yaml"


def cli(*args: str, env: dict[str, str] | None = None, **kw) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=120, env=env, **kw)


def scenario_with(tmp_path: Path, old: str, new: str, name: str = "s.yaml") -> Path:
    text = SHORT.read_text()
    assert old in text
    p = tmp_path / name
    p.write_text(text.replace(old, new, 1))
    return p


def test_a_binary_scenario_file_is_named(tmp_path):
    p = tmp_path / "binary.yaml"
    p.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\xff")
    with pytest.raises(ConfigError, match=r"binary.yaml: not a scenario file \(not UTF-8 text"):
        load_scenario(p)


def test_a_directory_given_as_scenario_is_called_a_directory(tmp_path):
    with pytest.raises(ConfigError, match="is a directory, not a scenario file"):
        load_scenario(tmp_path)


def test_a_scenario_name_is_not_shadowed_by_a_folder_of_that_name(tmp_path, monkeypatch):
    """`run im_short --out im_short` once, then `run im_short` again from the same folder: the
    name is still the scenario's."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "im_short").mkdir()
    assert load_scenario("im_short").name == "im_short"
    with pytest.raises(ConfigError, match="is a directory, not a scenario file"):
        load_scenario("./im_short")  # a path: the folder it names


def test_numbers_read_as_rcl_reads_them(tmp_path):
    """`ts: 5e-5` is a number to rcl's --params-file; so it is here."""
    p = scenario_with(tmp_path, "ts: 5.0e-05", "ts: 5e-5")
    assert load_scenario(p).ts == 5e-5


def test_a_key_given_twice_is_an_error(tmp_path):
    p = scenario_with(tmp_path, "    u_dc: 582.0", "    u_dc: 582.0\n    u_dc: 600.0")
    with pytest.raises(ConfigError, match="key 'u_dc' given twice"):
        load_scenario(p)


@pytest.mark.parametrize(
    "old, new, words",
    [
        ("window_end: 0.4", "window_end: 0.6", "window_end 0.6 s lies beyond the run"),
        ("thd_window: []", "thd_window: [0.1, 0.9]", "thd_window ends at 0.9 s, beyond the run"),
        ("duration: 0.4 ", "duration: 4.0e+9 ", r"8e\+13 steps; at most 1e\+09"),
        ("duration: 0.4 ", "duration: 1.0e-5 ", "shorter than one control period"),
    ],
    ids=["window", "thd-window", "huge", "sub-step"],
)
def test_senseless_lengths_are_refused_with_the_numbers(tmp_path, old, new, words):
    with pytest.raises(ConfigError, match=words):
        load_scenario(scenario_with(tmp_path, old, new))


def test_a_duration_shorter_than_one_step_is_refused_on_the_command_line():
    with pytest.raises(ConfigError, match=r"duration 1e-06 s is shorter than one control period"):
        run("im_short", duration=1e-6, engine="inprocess", out="/nonexistent/never")


def test_a_switch_to_the_strategy_in_force_is_refused(tmp_path):
    with pytest.raises(ConfigError, match="--switch 0.1:db_mptc: db_mptc is already"):
        run("im_short", switches=[(0.1, "db_mptc")], engine="inprocess", out=tmp_path / "b")


@pytest.mark.parametrize("engine", ["inprocess", "ros", "composed"])
@pytest.mark.parametrize("case", ["file", "bag", "folder", "below-a-file", "unwritable"])
def test_out_is_checked_before_anything_starts(tmp_path, engine, case):
    target = tmp_path / "out"
    if case == "file":
        target.write_text("x")
        words = "a file of that name exists"
    elif case == "bag":
        shutil.copytree(Path(__file__).parent, target / "x")  # any content
        (target / "x_0.mcap").write_bytes(b"")
        words = "a bag of that name exists"
    elif case == "folder":
        (target / "notes").mkdir(parents=True)
        words = "a folder of that name exists"
    elif case == "below-a-file":
        (tmp_path / "f").write_text("x")
        target = tmp_path / "f" / "out"
        words = "is a file, not a folder"
    else:
        if os.geteuid() == 0:
            pytest.skip("root writes anywhere")
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(stat.S_IRUSR | stat.S_IXUSR)
        target = ro / "out"
        words = "is not writable"
    before = sorted(tmp_path.rglob("*"))
    with pytest.raises(BagError, match=words):
        run("im_short", duration=0.01, engine=engine, out=target)
    assert sorted(tmp_path.rglob("*")) == before  # nothing started, nothing written


def test_json_failure_is_a_json_object(tmp_path):
    r = cli("run", "nope", "--json", "--engine", "inprocess")
    assert r.returncode == 2
    d = json.loads(r.stdout)
    assert d["kind"] == "ConfigError" and "unknown scenario 'nope'" in d["error"]
    assert "Traceback" not in r.stderr


@pytest.fixture(scope="module")
def short_bag(tmp_path_factory):
    out = tmp_path_factory.mktemp("bags") / "short"
    run_inprocess_to_bag(load_scenario("im_short", duration=0.05), out)
    return out


def test_a_closed_pipe_is_no_traceback(short_bag):
    r = subprocess.run(
        f"{' '.join(CLI)} report {short_bag} | head -c 1",
        shell=True,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert "Traceback" not in r.stderr and "BrokenPipe" not in r.stderr


def test_two_mcap_files_or_garbage_metadata_are_errors(short_bag, tmp_path):
    two = tmp_path / "two"
    shutil.copytree(short_bag, two)
    shutil.copy(two / "short_0.mcap", two / "other_0.mcap")
    with pytest.raises(BagError, match="2 .mcap files"):
        read_bag(two)
    garbage = tmp_path / "garbage"
    shutil.copytree(short_bag, garbage)
    (garbage / "metadata.yaml").write_text("{{{ not yaml")
    with pytest.raises(BagError, match="metadata.yaml: not rosbag2 metadata"):
        read_bag(garbage)


def test_a_truncated_recording_is_called_truncated_and_short(short_bag, tmp_path):
    cut = tmp_path / "cut"
    shutil.copytree(short_bag, cut)
    f = cut / "short_0.mcap"
    f.write_bytes(f.read_bytes()[: int(f.stat().st_size * 0.7)])
    r = cli("report", str(cut))
    assert r.returncode == 0, r.stderr
    assert "the recording is truncated" in r.stdout and "predictive-drive repair" in r.stdout
    assert "the run stopped early:" in r.stdout and "of 1000 planned steps recorded" in r.stdout


def _limit_file_size() -> None:
    resource.setrlimit(resource.RLIMIT_FSIZE, (300_000, 300_000))


def test_a_full_disk_in_process_is_a_clear_error(tmp_path):
    """The file-size limit stands in for a full disk (the write fails alike); the message says
    what happened and what the bag holds."""
    import signal

    out = tmp_path / "full"
    r = subprocess.run(
        [*CLI, "run", "im_short", "--engine", "inprocess", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=lambda: (signal.signal(signal.SIGXFSZ, signal.SIG_IGN), _limit_file_size()),
    )
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr
    assert f"writing the bag {out} failed (File too large)" in r.stderr or (
        f"closing the bag {out} failed" in r.stderr
    )
    rep = cli("report", str(out))
    assert "truncated" in rep.stdout or rep.returncode == 2  # never a good bag


def test_domain_locks_are_open_to_every_user():
    from predictive_drive.ros.processes import LOCK_DIR, isolated_domain

    with isolated_domain() as d:
        assert stat.S_IMODE(LOCK_DIR.stat().st_mode) == 0o1777
        assert stat.S_IMODE((LOCK_DIR / f"{d}.lock").stat().st_mode) == 0o666


def test_a_bad_domain_id_is_named():
    r = cli("param", "get", "plant", "u_dc", env={**os.environ, "ROS_DOMAIN_ID": "abc"})
    assert r.returncode == 2
    assert "ROS_DOMAIN_ID='abc': expected a whole number from 0 to 232" in r.stderr
    assert "Traceback" not in r.stderr


@pytest.mark.process
def test_the_node_logs_stay_with_the_bag(tmp_path):
    """The graph's logs and parameter overrides go into <bag>/logs, no temp folder elsewhere."""
    import tempfile

    before = set(Path(tempfile.gettempdir()).iterdir())
    r = run("im_short", duration=0.01, engine="ros", out=tmp_path / "b")
    logs = r.bag / LOGS_DIR
    assert {p.name for p in logs.iterdir()} >= {"overrides.yaml", "plant.log", "metrics_logger.log"}
    made = set(Path(tempfile.gettempdir()).iterdir()) - before
    assert not [p for p in made if p.name.startswith("tmp")]
