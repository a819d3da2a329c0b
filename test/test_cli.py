"""The command line's own behaviour: plain-text help, every verb listed, and an option that does
not apply in a mode refused with the reason (exit 2) before anything runs."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import pytest

from predictive_drive import cli

pytestmark = pytest.mark.core


def test_help_is_plain_text_and_lists_every_verb(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert "``" not in out and ":mod:" not in out  # no reST markup
    for verb in cli.VERBS:
        assert f"    {verb}" in out, verb
    for verb in cli.VERBS:
        with pytest.raises(SystemExit):
            cli.main([verb, "--help"])
        text = capsys.readouterr().out
        assert text.startswith(f"usage: predictive-drive {verb}") and "``" not in text


REFUSED = [
    (["run", "im_short", "--engine", "inprocess", "--sched", "batch"],
     "--sched applies to --engine ros only"),
    (["run", "im_short", "--composed", "--affinity", "none"], "--affinity applies to --engine ros"),
    (["run", "im_short", "--engine", "inprocess", "--peer-timeout", "3"],
     "--peer-timeout applies to the ROS engines only"),
    (["replay", "b", "--strategy", "mptc"], "--strategy applies with --into only"),
    (["replay", "b", "--out", "x"], "--out applies with --into only"),
    (["replay", "b", "--into", "torque_controller", "--rate", "2"],
     "--rate is an option of playing onto topics, not of --into"),
    (["replay", "b", "--into", "torque_controller", "--topics", "/clock"], "--topics is an option"),
    (["replay", "b", "--into", "torque_controller", "--loop"], "--loop is an option"),
    (["reproduce", "im_paper", "--repeats", "3"], "--repeats times the compute ratios"),
    (["sweep", "im_short", "--scheduler", "tcp://x:1", "--jobs", "2"], "--jobs sets the local"),
    (["bench", "--quick", "--steps", "100"], "--steps sets what --quick sets already"),
    (["bench", "--no-ros", "--graph", "ros"], "--graph chooses graph runs, and --no-ros skips"),
    (["bench", "--graph", "ros,dtc"], "--graph dtc: not a graph run; one of ros, ros_immediate"),
    (["run", "im_short", "--label", "dtc"], "--label dtc: names a node of your own"),
    (["run", "im_short", "--engine", "inprocess", "--startup-timeout", "3"],
     "--startup-timeout applies to the ROS engines only"),
    (["replay", "b", "--wait-for", "2", "--into", "torque_controller"],
     "--wait-for is an option of playing onto topics"),
    (["replay", "b", "--label", "x"], "--label applies with --into only"),
    (["run", "im_short", "--engine", "inprocess", "--external", "torque_controller=x"],
     "--external runs your node as a process of its own: --engine ros, not inprocess"),
    (["run", "im_short", "--external", "plant=x"],
     "--external plant: not a node you can replace; one of torque_controller, speed_pi"),
    (["run", "im_short", "--strategy", "mptc", "--external", "torque_controller=x"],
     "so --strategy and --switch do not apply"),
    (["run", "im_short", "--external", "torque_controller= "], "an empty command"),
    (["reproduce", "im_paper", "--scheduler", "tcp://x:1"],
     "--scheduler serves the realism, fronts, robustness and efficiency studies only"),
    (["reproduce", "fronts", "--draws", "5"],
     "--draws chooses the robustness study's drives, not fronts's"),
]  # fmt: skip


@pytest.mark.parametrize("args,message", REFUSED, ids=[" ".join(a[:3]) for a, _ in REFUSED])
def test_an_option_that_does_not_apply_is_refused_with_the_reason(
    args, message, capsys, tmp_path, monkeypatch
):
    monkeypatch.chdir(tmp_path)  # where a run would write its bags/
    assert cli.main([*args, "--json"]) == 2
    out, err = capsys.readouterr()
    assert message in err, err
    assert json.loads(out)["kind"] == "ConfigError"
    assert not list(tmp_path.iterdir())  # nothing ran, nothing written


# --- the promises the command line keeps (docs and --help say them) -------------------------


def run_cli(args: list[str], capsys) -> tuple[int, str, str]:
    """``predictive-drive ARGS`` in this process: exit status, stdout, stderr."""
    try:
        code = cli.main(args)
    except SystemExit as e:  # argparse's usage errors
        code = int(e.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def test_every_verb_takes_json(capsys, tmp_path, monkeypatch):
    """`--json` on every verb, as the README says: layout and param too (an error is one JSON
    object as well)."""
    for verb in cli.VERBS:
        with pytest.raises(SystemExit):
            cli.main([verb, "--help"])
        assert "--json" in capsys.readouterr().out, verb
    monkeypatch.chdir(tmp_path)
    code, out, _ = run_cli(["layout", "--json"], capsys)
    assert code == 0 and json.loads(out) == {"layout": "drive.foxglove.json", "replaced": False}
    # param: the usage error of `get` with a value comes as JSON before any ROS is touched
    code, out, err = run_cli(["param", "get", "plant", "u_dc", "1", "--json"], capsys)
    assert code == 2 and json.loads(out)["error"] == "param get takes NODE NAME only", err


def test_layout_does_not_overwrite_a_file_unless_told(capsys, tmp_path):
    f = tmp_path / "mine.json"
    f.write_text("my own layout\n")
    code, out, err = run_cli(["layout", "--out", str(f)], capsys)
    assert code == 2 and "the file exists; --force replaces it" in err
    assert f.read_text() == "my own layout\n"
    code, out, _ = run_cli(["layout", "--out", str(f), "--force"], capsys)
    assert code == 0 and out.startswith(f"replaced {f}:")
    assert json.loads(f.read_text())["configById"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.json"]  # no temporary left


def test_live_without_foxglove_is_refused_before_it_says_where_it_serves(
    capsys, tmp_path, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(sys.modules, "foxglove", None)  # import foxglove: ModuleNotFoundError
    args = ["run", "im_short", "--engine", "inprocess", "--duration", "0.01", "--live"]
    code, out, err = run_cli(args, capsys)
    assert code == 2, err
    assert "--live needs the Python package foxglove-sdk, which is not installed: pip" in err
    assert "no rosdep key" in err and "live view on" not in err
    assert not list(tmp_path.iterdir())  # refused before anything ran


def test_sweep_writes_a_csv_table_without_pyarrow(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    sweep = ["sweep", "im_short", "--strategy", "mptc,db_mptc", "--duration", "0.01"]
    code, out, err = run_cli([*sweep, "--out", "table.csv"], capsys)
    assert code == 0, err
    assert "wrote    table.csv" in out
    rows = (tmp_path / "table.csv").read_text().splitlines()
    assert rows[0].startswith("strategy,t_rmse,") and [r.split(",")[0] for r in rows[1:]] == [
        "mptc", "db_mptc"
    ]  # fmt: skip
    # a folder gets the Parquet table too: without pyarrow that is refused before any run
    code, out, err = run_cli([*sweep, "--out", "tables"], capsys)
    assert code == 2 and "pyarrow" in err and "FILE.csv: the CSV alone" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["table.csv"]


def test_help_names_the_scenarios_and_the_defaults(capsys):
    from predictive_drive.config import scenario_names

    with pytest.raises(SystemExit):
        cli.main(["run", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert all(name in text for name in scenario_names()) and "im_paper, im_short" in text
    with pytest.raises(SystemExit):
        cli.main(["reproduce", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "(default: inprocess," in text


BAD_VALUES = [
    (["run", "im_short", "--duration", "-1"],
     "argument --duration: expected a positive number of seconds, got '-1'"),
    (["sweep", "im_short", "--duration", "nan"],
     "argument --duration: expected a positive number of seconds, got 'nan'"),
    (["reproduce", "im_paper", "--duration", "0"],
     "argument --duration: expected a positive number of seconds, got '0'"),
    (["run", "im_short", "--engine", "inprocess", "--set", "plant.dead_time=-1"],
     "im_short --set plant.dead_time=-1: /drive/plant: dead_time must be a finite number >= 0 s"),
    (["run", "im_short", "--engine", "inprocess", "--set", "torque_controller.motor.l_m=-1"],
     "/drive/torque_controller.motor: l_m must be a finite number > 0 H, got -1"),
    (["sweep", "im_short", "--set", "lambda_psi=0,50"],
     "setting 'lambda_psi': /** has no key 'lambda_psi' here; did you mean "
     "torque_controller.lambda_psi?"),
    (["sweep", "im_short", "--set", "r_s=1"],
     "did you mean plant.motor.r_s or torque_controller.motor.r_s?"),
]  # fmt: skip


@pytest.mark.parametrize("args,message", BAD_VALUES, ids=[" ".join(a[-2:]) for a, _ in BAD_VALUES])
def test_a_bad_value_is_named_as_the_user_wrote_it(args, message, capsys, tmp_path, monkeypatch):
    """The option or the dotted key, never a class of the code (RunParams.duration)."""
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli(args, capsys)
    assert code == 2 and message in err, err
    assert not re.search(r"\b[A-Z][A-Za-z]+\.[a-z_]+\b", err.split("error:", 1)[1]), err
    assert not list(tmp_path.iterdir())


def test_an_unknown_option_is_said_with_the_verbs_usage(capsys):
    code, _, err = run_cli(["run", "im_short", "--bogus"], capsys)
    assert code == 2
    assert err.startswith("usage: predictive-drive run [-h] [--json]"), err
    assert "predictive-drive run: error: unrecognized arguments: --bogus" in err


def test_a_paused_replay_says_how_to_resume(capsys, monkeypatch):
    from predictive_drive.cli import replay as replay_verb
    from predictive_drive.errors import BagError

    def no_replay(bag, **options):  # what is said before the replay starts is what matters
        assert options["start_paused"]
        raise BagError("not a recording")

    monkeypatch.setattr(replay_verb, "replay", no_replay)
    monkeypatch.setenv("ROS_DOMAIN_ID", "42")
    code, _, err = run_cli(["replay", "some_bag", "--start-paused"], capsys)
    assert code == 2
    assert (
        "the replay starts paused; to start it, from another shell: ROS_DOMAIN_ID=42 "
        "predictive-drive param set player paused false"
    ) in err


def test_the_run_printout_says_what_its_lines_are(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(["run", "im_short", "--engine", "inprocess"], capsys)
    assert code == 0, err
    lines = {line.split()[0]: line for line in out.splitlines()}
    assert lines["window"].endswith(
        "the figures below are over it (the scenario's, cut to the run)"
    )
    assert lines["speed_RMSE"].endswith("omega_m vs omega_m*, its steps (start, reversal) included")
    assert lines["vectors"].endswith("share of steps per vector, V0 zero")
    after = out.split("  outcome ", 1)[1].splitlines()[1]
    assert after.strip() == (
        "the recorder's verdict; its figures cover the whole run, T_RMSE above the window"
    )
    assert " cont " not in out  # no period means recorded: no continuous-time figures


def test_run_and_report_print_the_figures_the_fronts_rank_by(capsys, tmp_path, monkeypatch):
    """With the plant's period means (the steady points record them) run and report print the
    continuous-time figures, aligned with the rest (was: only compare and --json had them)."""
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(
        ["run", "im_steady", "--engine", "inprocess", "--duration", "0.1", "--out", "b"], capsys
    )
    assert code == 0, err
    code, again, err = run_cli(["report", "b"], capsys)
    for text in (out, again):
        lines = {line[:16].strip(): line for line in text.splitlines() if line.startswith("  ")}
        assert {"T_RMSE cont", "T_ripple cont", "THD_i cont"} <= set(lines), text
        assert lines["T_ripple cont"].index("N·m") == lines["T_RMSE"].index("N·m")


MISSING = """\
import sys
sys.modules[sys.argv[1]] = None  # as if it were not installed
from predictive_drive.cli import main
sys.exit(main(sys.argv[2:]))
"""


@pytest.mark.parametrize(
    "module,args,says",
    [
        ("mcap", ["--help"], "the Python package mcap is not installed: pip install 'mcap'; in a "
         "ROS workspace, rosdep install --from-paths src --ignore-src -y (its key: "
         "mcap-ros2-support)"),
        ("yaml", ["run", "--help"], "the Python package PyYAML is not installed"),
        ("rclpy", ["param", "get", "plant", "u_dc"],
         "the ROS 2 package rclpy is not installed: source a ROS 2 Jazzy install"),
        # a graph's nodes would fail after the launch: refused before, no bag folder left
        ("rcl_interfaces", ["run", "im_short", "--duration", "0.02", "--out", "b"],
         "--engine ros needs the ROS 2 package rcl_interfaces, which is not installed: source a "
         "ROS 2 Jazzy install (. /opt/ros/jazzy/setup.sh) or pip install 'predictive_drive[ros]'; "
         "or run in-process (--engine inprocess), which needs no ROS"),
    ],
    ids=["mcap-help", "yaml-verb-help", "rclpy-param", "rcl_interfaces-run"],
)  # fmt: skip
def test_a_missing_package_is_one_line_naming_it_and_how_to_install_it(
    module, args, says, tmp_path
):
    r = subprocess.run(
        [sys.executable, "-c", MISSING, module, *args],
        cwd=tmp_path, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert r.returncode == 2, r.stderr
    (line,) = r.stderr.splitlines()  # one line, no traceback
    assert line.startswith("predictive-drive: error: ") and says in line, line
    assert list(tmp_path.iterdir()) == []  # nothing started, nothing written


@pytest.mark.core
def test_the_printout_reads_dash_for_what_a_controller_cannot_have(capsys, tmp_path):
    """A FOC run picks no vector and reports no t_u: deadbeat reads '-' without its unit and no
    vectors line is printed (was: 'deadbeat 0.00 %', 'vectors V0 nan% ...')."""
    code, out, _ = run_cli(
        ["run", "ipmsm_mtpa_short", "--engine", "inprocess", "--duration", "0.02", "--out",
         str(tmp_path / "foc")], capsys,
    )  # fmt: skip
    assert code == 0
    assert re.search(r"^  deadbeat +-   steps with", out, re.MULTILINE), out
    assert "nan" not in out.lower() and "- %" not in out and "vectors" not in out, out
