"""Bad input and faults (issue: nothing lost, nothing false): every case ends with a clear error
naming the file, key or value, no traceback, nothing half-written presented as a good bag."""

from __future__ import annotations

import json
import os
import re
import resource
import shutil
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mcapcheck import rewrite_bag
from predictive_drive.api.run import run, run_inprocess_to_bag
from predictive_drive.config import config_dir, load_scenario
from predictive_drive.errors import BagError, ConfigError
from predictive_drive.readback import read_bag
from procs import kill_if_running

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


@pytest.mark.parametrize("engine", ["inprocess", "composed", "ros"])
@pytest.mark.parametrize(
    "switch, words",
    [
        ((0.1, "db_mptc"), "--switch 0.1:db_mptc: db_mptc is already the strategy then"),
        ((5.0, "mptc"), r"--switch 5.0:mptc: time must lie in \[0, 0.4\) s"),
        ((-0.1, "mptc"), r"--switch -0.1:mptc: time must lie in \[0, 0.4\) s"),
        ((0.1, "dtc"), "--switch 0.1:dtc: unknown strategy; valid: mptc, mptc_db, db_mptc"),
    ],
)
def test_a_switch_the_run_cannot_take_is_refused_on_every_engine(tmp_path, engine, switch, words):
    """Refused before anything starts (no node, no bag), whichever engine would run it."""
    with pytest.raises(ConfigError, match=words):
        run("im_short", duration=0.4, switches=[switch], engine=engine, out=tmp_path / "b")
    assert not (tmp_path / "b").exists()


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


#: a failing call of every verb that takes --json: (arguments, error kind, words of the message)
_JSON_CASES = [
    (("run", "nope", "--engine", "inprocess"), "ConfigError", "unknown scenario 'nope'"),
    (("report", "/no/bag"), "BagError", "/no/bag"),
    (("compare", "/no/a", "/no/b"), "BagError", "/no/a"),
    (("sweep", "nope"), "ConfigError", "unknown scenario 'nope'"),
    (("reproduce", "nope"), "UsageError", "invalid choice: 'nope'"),
    (("analyze", "/no/bag"), "BagError", "/no/bag"),
    (("replay", "/no/bag"), "BagError", "/no/bag"),
    (("repair", "/no/bag"), "BagError", "/no/bag"),
    (("bench", "--steps", "0"), "ConfigError", "--steps 0: must be at least 2000"),
    (("layout", "--out", "/proc/drive.foxglove.json"), "ConfigError", "cannot write it"),
    (("param", "get", "plant", "u_dc", "1"), "ConfigError", "param get takes NODE NAME only"),
    (
        ("param", "get", "plant", "u_dc", "--timeout", "0"),
        "ConfigError",
        "--timeout 0: a number of seconds above 0",
    ),
    (("run", "im_short", "--no-such-option"), "UsageError", "unrecognized arguments"),
]


@pytest.mark.parametrize(
    "args, kind, words", _JSON_CASES, ids=[" ".join(c[0]) for c in _JSON_CASES]
)
def test_json_failure_is_a_json_object_for_every_verb(args, kind, words):
    """With --json, a failure is one JSON object on stdout (the message also on stderr),
    exit 2, for every verb that takes --json."""
    r = cli(*args, "--json")
    assert r.returncode == 2, r.stderr
    d = json.loads(r.stdout)
    assert d["kind"] == kind and words in d["error"], d
    assert f"predictive-drive: error: {d['error']}" in r.stderr and "Traceback" not in r.stderr


def test_every_verb_with_json_has_its_failure_case():
    from predictive_drive.cli import VERBS

    assert {c[0][0] for c in _JSON_CASES} == set(VERBS)  # every verb takes --json


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
    said = re.search(rf"writing the bag {out} failed \(File too large\) after (\d+) messages; "
                     r"it has no index", r.stderr)  # fmt: skip
    assert said, r.stderr
    rep = cli("report", str(out))  # never presented as a good bag
    assert rep.returncode == 0 and "the recording is truncated" in rep.stdout, rep.stderr


def test_domain_locks_are_open_to_every_user():
    from predictive_drive.ros.processes import LOCK_DIR, isolated_domain

    with isolated_domain() as d:
        assert stat.S_IMODE(LOCK_DIR.stat().st_mode) == 0o1777
        assert stat.S_IMODE((LOCK_DIR / f"{d}.lock").stat().st_mode) == 0o666


def test_a_held_domain_is_held_whatever_temporary_folder_a_process_has(tmp_path):
    """Two processes with different TMPDIRs (each pytest worker's runs have one) never take one
    domain: the lock files are machine-wide. A CI call met two graphs on one domain (47), each
    taking the other's commands, when the lock folder followed TMPDIR."""
    from predictive_drive.ros.processes import isolated_domain

    code = (
        "from predictive_drive.ros.processes import isolated_domain\n"
        "from predictive_drive.errors import GraphError\n"
        "try:\n"
        "    with isolated_domain(range(231, 232)) as d: print('took', d)\n"
        "except GraphError as e: print(e)\n"
    )  # fmt: skip
    with isolated_domain(range(231, 232)) as d:
        assert d == 231
        r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           timeout=60, env={**os.environ, "TMPDIR": str(tmp_path)})  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "no free ROS domain id in 231..231: 1 predictive_drive runs at once?"


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["ctrl-c", "sigterm"])
def test_a_press_after_the_command_has_said_everything_keeps_its_status(tmp_path, sig):
    """Signals from the moment the command's last line is out until the process is gone (one
    every 0.5 ms): it exits with its own status, 0, or as interrupted (130) if one lands before
    main() has returned, never killed by the signal. Was: Python resets its handlers for the
    last part of its exit, and a press there ended the process by the signal (-2), as a sweep
    did after a double Ctrl-C in 3 of 12 calls."""
    p = subprocess.Popen(
        [*CLI, "run", "im_short", "--engine", "inprocess", "--duration", "0.005",
         "--out", str(tmp_path / "b")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        for line in p.stdout:
            if "the recorder's verdict" in line:
                break
        sent, deadline = 0, time.monotonic() + 30
        while p.poll() is None and time.monotonic() < deadline:
            try:
                p.send_signal(sig)
            except ProcessLookupError:
                break
            sent += 1
            time.sleep(0.0005)
        _, stderr = p.communicate(timeout=30)
    finally:
        kill_if_running(p)
    assert sent > 0
    assert p.returncode in (0, 130), (p.returncode, sent, stderr)
    assert "Traceback" not in stderr


def test_a_bad_domain_id_is_named():
    r = cli("param", "get", "plant", "u_dc", env={**os.environ, "ROS_DOMAIN_ID": "abc"})
    assert r.returncode == 2
    assert "ROS_DOMAIN_ID='abc': expected a whole number from 0 to 232" in r.stderr
    assert "Traceback" not in r.stderr


def _cut(bag: Path, dest: Path, keep: int) -> Path:
    """A copy of ``bag`` in 16 KiB chunks (the mcap library's writer) whose file keeps its
    first ``keep`` bytes: a writer killed there, with whole chunks before the cut (the
    recorder's own chunks of 768 KiB hold the whole of this short run)."""
    rewrite_bag(bag, dest, chunk_size=16 * 1024)
    (f,) = dest.glob("*.mcap")
    f.write_bytes(f.read_bytes()[:keep])
    return dest


def test_a_recording_cut_before_its_metrics_window_is_reported_over_what_it_holds(
    short_bag, tmp_path
):
    """Cut a few hundred steps in, before the 0.05 s window starts: report says so and reports
    over the steps there are (was: a ValueError traceback)."""
    cut = _cut(short_bag, tmp_path / "cut", 120_000)
    r = cli("report", str(cut))
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    steps = read_bag(cut)[0].steps
    assert 0 < steps < 1000  # the window starts at step 1000
    held = steps * 5e-5
    assert f"window   0-{held:.4g} s ({steps} steps)" in r.stdout
    assert f"the recording ends at {held:g} s, inside or before the metrics window 0.05-0.4 s: " \
        f"the metrics cover 0-{held:g} s" in r.stdout  # fmt: skip


@pytest.mark.parametrize(
    "content,words",
    [
        (b"", "the file is empty (0 bytes): its writer was killed before it wrote anything"),
        (b"\x89MCAP0\r\n", "cut short before anything was recorded (8 bytes"),
        (os.urandom(4096), "not an MCAP file (it does not begin with MCAP's magic bytes)"),
    ],
    ids=["empty", "header-only", "random-bytes"],
)
@pytest.mark.parametrize("verb", ["report", "replay", "repair", "analyze"])
def test_a_file_that_is_no_recording_is_called_what_it_is(tmp_path, content, words, verb):
    f = tmp_path / "x.mcap"
    f.write_bytes(content)
    r = cli(verb, str(f), env={**os.environ, "ROS_DOMAIN_ID": "231"})
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert words in r.stderr, r.stderr


@pytest.mark.parametrize("verb", ["report", "repair"])
def test_random_bytes_in_a_bag_folder_are_not_an_mcap_file(tmp_path, verb):
    """A bag folder whose .mcap holds random bytes is named what it is, as the file itself is
    (was: "cut short before anything was recorded (… the file's header only)"); repair leaves
    it as it was."""
    bag = tmp_path / "bag"
    bag.mkdir()
    junk = os.urandom(200_000)
    (bag / "bag_0.mcap").write_bytes(junk)
    r = cli(verb, str(bag))
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert "not an MCAP file (it does not begin with MCAP's magic bytes)" in r.stderr, r.stderr
    assert sorted(p.name for p in bag.iterdir()) == ["bag_0.mcap"]
    assert (bag / "bag_0.mcap").read_bytes() == junk


def _first_chunk_at(path: Path) -> int:
    """The offset of a file's first Chunk record (MCAP records: opcode, u64 length, body)."""
    data = path.read_bytes()
    at = 8  # the magic
    while data[at] != 0x06:  # opcode Chunk
        at += 9 + int.from_bytes(data[at + 1 : at + 9], "little")
    return at


def test_repair_of_a_bag_without_a_complete_step_leaves_it_as_it_was(short_bag, tmp_path):
    """Cut inside the first chunk: the metadata is there, no step is. repair says so and
    changes nothing (was: the file rewritten, then "holds no complete step")."""
    cut = tmp_path / "cut"
    rewrite_bag(short_bag, cut, chunk_size=16 * 1024)
    (f,) = cut.glob("*.mcap")
    f.write_bytes(f.read_bytes()[: _first_chunk_at(f) + 100])
    before, held = f.read_bytes(), sorted(p.name for p in cut.iterdir())
    r = cli("repair", str(cut))
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert "the recording holds no complete step; nothing repaired: the file is left as it " \
        "was" in r.stderr  # fmt: skip
    assert f.read_bytes() == before and sorted(p.name for p in cut.iterdir()) == held


def test_a_thd_window_without_a_whole_cycle_is_a_note_and_report_takes_other_windows(tmp_path):
    """A THD window the run turns less than a cycle in: the run prints its metrics, THD "-" and
    a note (was: a ValueError traceback after the run, and a bag `report` could never read);
    `report --window A,B --thd-window A,B` evaluates the recording over others."""
    bag = tmp_path / "bag"
    r = cli("run", "im_short", "--engine", "inprocess", "--duration", "1", "--set",
            "metrics_logger.thd_window=[0.1,0.102]", "--out", str(bag), "--json")  # fmt: skip
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    d = json.loads(r.stdout)
    assert d["metrics"]["thd"] is None and d["metrics"]["t_rmse"] > 0
    assert "no THD: THD window [0.1, 0.102) s holds no whole electrical cycle (0.0" \
        in d["window_note"]  # fmt: skip
    r = cli("report", str(bag), "--window", "0.4,1.0", "--thd-window", "0.4,1.0", "--json")
    assert r.returncode == 0, r.stderr
    m = json.loads(r.stdout)["metrics"]
    assert (m["t_start"], m["t_end"], m["steps"]) == (0.4, 1.0, 12000)
    assert m["thd"] > 0 and m["thd_cycles"] >= 1
    for option, value, said in (
        ("--window", "0.5,2", "--window 0.5,2: ends beyond the run (1 s)"),
        ("--thd-window", "0.3,0.2", "--thd-window 0.3,0.2: need 0 <= A < B (s)"),
    ):
        r = cli("report", str(bag), option, value)
        assert r.returncode == 2 and said in r.stderr and "Traceback" not in r.stderr, r.stderr


def test_layout_to_a_path_that_cannot_be_written_is_an_error():
    r = cli("layout", "--out", "/proc/drive.foxglove.json")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "layout --out /proc/drive.foxglove.json: cannot write it:" in r.stderr


def test_repair_without_room_says_the_original_is_intact(short_bag, tmp_path):
    cut = _cut(short_bag, tmp_path / "cut", 200_000)
    before = (cut / "cut_0.mcap").read_bytes()
    held = sorted(p.name for p in cut.iterdir())
    r = subprocess.run(
        [*CLI, "repair", str(cut)], capture_output=True, text=True, timeout=120,
        preexec_fn=lambda: (signal.signal(signal.SIGXFSZ, signal.SIG_IGN),
                            resource.setrlimit(resource.RLIMIT_FSIZE, (50_000, 50_000))),
    )  # fmt: skip
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert "which failed (File too large); the original is intact: copy the bag to a disk with " \
        "room and repair the copy" in r.stderr  # fmt: skip
    assert (cut / "cut_0.mcap").read_bytes() == before  # intact
    assert sorted(p.name for p in cut.iterdir()) == held  # nothing added, nothing removed
    assert not list(tmp_path.glob(".cut.repair-*"))  # its temporary copy removed


def test_ctrl_c_at_any_moment_is_an_exit_status_not_a_traceback(tmp_path):
    """SIGINT while Python imports the command line and its verbs (it took 0.4 s and gave a
    KeyboardInterrupt traceback), or while the run goes: exit 130, no traceback. Python's own
    start-up (before the package's first line, measured here) cannot be helped; the first
    delay is twice it."""
    import time

    t0 = time.perf_counter()
    # what Python does before the package's first line (which takes Ctrl-C over)
    subprocess.run([sys.executable, "-c", "import os, signal"], check=True, timeout=60)
    startup = time.perf_counter() - t0
    for n, delay in enumerate((2 * startup, 3 * startup, 0.2, 0.3, 0.5, 1.0)):
        # a run that takes far longer than the delay: the signal always finds it running
        p = subprocess.Popen([*CLI, "run", "im_short", "--engine", "inprocess", "--duration",
                              "60", "--out", str(tmp_path / f"b{n}")], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)  # fmt: skip
        time.sleep(delay)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=60)
        assert "Traceback" not in err and "KeyboardInterrupt" not in err, (delay, err)
        assert p.returncode == 130, (delay, p.returncode, err)


@pytest.fixture
def unwritable(tmp_path):
    """A folder nothing can be written into, for root too (root passes every permission bit: a
    folder under /proc, where even root makes no file)."""
    if os.geteuid() == 0:
        return Path("/proc/predictive_drive_test")
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(stat.S_IRUSR | stat.S_IXUSR)
    return ro / "out"


def _refused_before_the_work(call, words, monkeypatch):
    """``call()`` fails with ``words`` before any run starts (a run would be the work lost)."""
    import predictive_drive.api.sweep as sweep_api

    def no_run(*a, **kw):
        raise AssertionError("a run started before the output was checked")

    monkeypatch.setattr(sweep_api, "run_case", no_run)
    monkeypatch.setattr(sweep_api, "run_cases", no_run)
    with pytest.raises(ConfigError) as e:
        call()
    assert words in str(e.value), e.value


@pytest.mark.parametrize("where", ["unwritable", "below a file"])
@pytest.mark.parametrize(
    "verb", ["reproduce --figures", "reproduce --bags", "sweep --figures", "sweep --out",
             "report --figures", "compare --figures", "layout --out"],
)  # fmt: skip
def test_every_output_is_checked_before_the_work(verb, where, unwritable, tmp_path, monkeypatch):
    """An output folder that cannot be written is refused before anything runs, naming the
    option, the path and why (was: `reproduce fronts --figures RO/figs` ran all 31 runs, then
    'Read-only file system', no table; `layout --out` under a file was a traceback)."""
    from predictive_drive.api.compare import compare
    from predictive_drive.api.report import report
    from predictive_drive.api.reproduce import reproduce
    from predictive_drive.api.sweep import sweep
    from predictive_drive.reports.layout import write_layout

    if where == "below a file":
        (tmp_path / "f").write_text("x")
        target, why = tmp_path / "f" / "out", f"{tmp_path / 'f'} is a file, not a folder"
    else:
        target, why = unwritable, "is not writable"
    calls = {
        "reproduce --figures": lambda: reproduce("fronts", figures=target, duration=0.01),
        "reproduce --bags": lambda: reproduce("im_paper", out_root=target, duration=0.01),
        "sweep --figures": lambda: sweep("im_short", figures=target, duration=0.01),
        "sweep --out": lambda: sweep("im_short", out=target / "t.csv", duration=0.01),
        "report --figures": lambda: report("/no/such/bag", figures=target),
        "compare --figures": lambda: compare(["/no/a", "/no/b"], figures=target),
        "layout --out": lambda: write_layout(target / "drive.foxglove.json"),
    }
    _refused_before_the_work(calls[verb], why, monkeypatch)
    assert verb.split()[-1] in str(pytest.raises(ConfigError, calls[verb]).value)


def test_an_unwritable_figures_folder_is_one_line_on_the_command_line(unwritable):
    why = "No such file or directory" if os.geteuid() == 0 else "Permission denied"
    r = cli("reproduce", "fronts", "--figures", str(unwritable), "--duration", "0.01")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip().splitlines() == [
        f"predictive-drive: error: --figures {unwritable}: cannot write there: "
        f"{unwritable.parent} is not writable ({why})"
    ]
