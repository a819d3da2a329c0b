"""The README's commands, run in order as a newcomer runs them: in a fresh copy of the checkout
(the files git has, nothing this checkout made since), in a fresh shell (no venv on PATH) with
the checkout's venv, each command in ``bash`` after the environment lines the README gave before
it (``. .venv/bin/activate``). Every command must exit 0, and the lines the README shows under a
``$ command`` must be in what it prints, in that order (``...`` skips lines).

The README's blocks: ```sh (every line a command, ``  # ...`` a comment) and ```console (``$``
lines are commands, the lines under one are what it prints). A block without a language is
output, never run.

To add a README block: write it; this test runs it. If it takes long, run it shorter here: add
the README's command to :data:`SHORTENED` with the command the test runs instead and why (its
output is then not compared). A command to run beside the next one, as from a second shell,
goes in :data:`ALONGSIDE`. A command that cannot run here (an install, the suite itself) goes in
:data:`NOT_RUN` with the reason or the test that runs it; so does every command of docs/*.md that
no test runs as written (test_every_command_of_the_docs_is_run_or_listed holds the list to the
pages).

The shell keeps this session's ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST: a
command that uses the environment's domain must not reach another session's graph.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import shlex
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from installs import ROOT, clean_env
from procs import end_all

#: README command → (the command the test runs instead, why). A shortened duration is marked
#: here and nowhere else.
SHORTENED = {
    "make run": (
        'make -o .venv/.installed run RUN_ARGS="--duration 0.2"',
        "the 6 s run takes minutes here; -o: the copy must never re-install the shared venv",
    ),
    "predictive-drive run im_paper --strategy mptc": (
        "predictive-drive run im_paper --strategy mptc --duration 2",
        "2 s of im_paper: long enough for the second shell's param set to land in the run",
    ),
    "predictive-drive reproduce im_paper": (
        "predictive-drive reproduce im_paper --duration 0.1",
        "the three 6 s runs take 12-30 s here",
    ),
    'predictive-drive run im_short --external "torque_controller=python3 '
    'examples/dtc_im/dtc_im/dtc_node.py"': (
        'predictive-drive run im_short --external "torque_controller=python3 '
        'examples/dtc_im/dtc_im/dtc_node.py" --duration 0.1',
        "the example node takes 6-30 s for the 0.4 s run here",
    ),
}

#: README command → the line of its stderr after which the next command runs beside it (as
#: from a second shell); the group is what ``N`` stands for in that next command
ALONGSIDE = {"predictive-drive run im_paper --strategy mptc": r"graph on ROS_DOMAIN_ID=(\d+)"}

#: commands of the README and docs/*.md this test does not run as written: why, or the test
#: that runs them
NOT_RUN = {
    # README.md
    "make test": "the suite this test is part of (CI runs it: .ci/run)",
    "make test TEST_WORKERS=1": "the same suite in one pytest worker",
    "time .ci/run": "the measurement of the README's timing (CI itself: make test)",
    'pip install ".[ros,figures]"': "test_install.py installs the wheel into a fresh venv",
    "ros2 run predictive_drive predictive-drive VERB ...": "no ros2 CLI from PyPI; "
    "test_install.py runs every verb from the colcon install's lib/predictive_drive",
    "rosdep install --from-paths src --ignore-src -y": "no rosdep here; test_colcon.py holds "
    "package.xml's keys to setup.py",
    "colcon build": "test_colcon.py and test_install.py build the workspace",
    "pip install foxglove-sdk": "make setup installs it (the [live] extra)",
    "predictive-drive VERB --help": "test_help_is_plain_text_and_lists_every_verb",
    # docs/ros.md
    "predictive-drive run ... &": "a form (a script's background run, stopped by its PID); "
    "test_one_ctrl_c_stops_a_run_that_shows_its_progress signals the launcher's own PID",
    "ROS_DOMAIN_ID=N predictive-drive param set torque_controller strategy mptc": "the README's "
    "second shell runs it with db_mptc; test_strategy_switch_through_param_cli",
    "ROS_DOMAIN_ID=N predictive-drive param get torque_controller strategy": (
        "test_every_verb_runs_from_the_install"
    ),
    "ROS_DOMAIN_ID=N predictive-drive param set torque_controller horizon 3": (
        "test_param_set_horizon_from_another_shell_lands_at_the_scheduled_step"
    ),
    # docs/physics.md
    "predictive-drive param set torque_controller horizon 3": (
        "test_param_set_horizon_from_another_shell_lands_at_the_scheduled_step"
    ),
    "pip install 'predictive_drive[fast]'": "make setup installs it (the [fast] extra)",
    "predictive-drive sweep SCENARIO --set ts=… --set torque_controller.current_target=sample,"
    "period_mean --json": "a template; test_field_orientation_holds_the_operating_point_on_its_"
    "mean_current runs five of its cells",
    "python test/continuous.py": "test_svpwm_distortion_is_the_fft_of_its_continuous_waveform "
    "runs two of its points through the same code (continuous.compare)",
    "predictive-drive run ipmsm_steady_mpc --engine inprocess --set torque_controller.horizon=10": (
        "5,000 steps at N = 10; test_a_budget_applies_the_best_so_far_and_report_counts_the_steps "
        "runs it for 0.05 s with a budget and reads report's line"
    ),
    # docs/reproduction.md
    "predictive-drive reproduce fronts": "635 runs, 2-6 min here; test_fronts.py runs a "
    "small study through the same code (api.fronts.reproduce_fronts)",
    "predictive-drive reproduce fronts --points im_steady --curves mptc,ifoc --periods-us none "
    '--external "torque_controller=python3 examples/dtc_im/dtc_im/dtc_node.py" --label dtc --knob '
    "torque_controller.torque_band=0.02,0.05,0.1,0.2 --figures figures": (
        "four graph runs of 1 s; test_your_controller_is_drawn_on_a_front_through_the_ros_graph "
        "runs the example on a front through the same code"
    ),
    "time predictive-drive reproduce fronts --json": "the timing of the command above",
    "predictive-drive reproduce fronts --json": "the command above, its table as JSON",
    "predictive-drive reproduce efficiency": "300 runs, over a minute here; test_efficiency.py "
    "runs a small grid through the same code (api.efficiency.reproduce_efficiency), "
    "test_install.py the verb",
    "predictive-drive reproduce efficiency --json": "the command above, its maps as JSON",
    "time predictive-drive reproduce efficiency --json": "the timing of the command above",
    "predictive-drive reproduce robustness": "hundreds of runs; test_robustness.py runs a short "
    "study through the same code (api.robustness.reproduce_robustness), test_install.py the verb",
    "predictive-drive reproduce robustness --draws 1000": "16,044 runs, most of an hour here",
    "time predictive-drive reproduce robustness --points ipmsm_steady --draws 1000": "the timing "
    "of 4,016 runs (minutes): a measurement, not a test",
    "predictive-drive run pmsyrm_steady --duration 0.02 --set plant.saturation.max_current=8": (
        "test_leaving_the_map_stops_the_run_naming_the_step_and_the_current"
    ),
    "cd ~/ws/src && git clone <this repository> predictive_drive && cd ~/ws": "a user's workspace; "
    "installs.colcon_install copies the package as a clone has it",
    "colcon build && . install/setup.sh": "test_colcon.py builds the workspace",
    "ros2 launch predictive_drive drive.launch.xml scenario:=im_paper strategy:=mptc "
    "live_port:=8765": "no launch package from PyPI; "
    "test_the_launch_file_starts_the_graph_the_launcher_starts",
    "ros2 run predictive_drive plant_node --ros-args --params-file "
    "install/predictive_drive/share/predictive_drive/config/im_paper.yaml": (
        "test_the_installed_nodes_run_as_ros2_run_starts_them"
    ),
    "ros2 run predictive_drive predictive-drive run im_short": "no ros2 CLI from PyPI; "
    "test_every_verb_runs_from_the_install (colcon)",
    "install/predictive_drive/lib/predictive_drive/predictive-drive run im_short": (
        "test_every_verb_runs_from_the_install (colcon)"
    ),
    "python3 -m predictive_drive.cli run im_short": "test_the_installed_package_is_the_one_running"
    " (the same module, from the colcon install's path)",
    "predictive-drive run SCENARIO --external torque_controller=COMMAND": "the README's example "
    "runs it; test_external.py",
    "predictive-drive replay BAG --into torque_controller=COMMAND [--label NAME]": (
        "test_replaying_the_example_into_itself_gives_its_commands_bit_for_bit, "
        "test_replay_into_a_controller_refuses_what_the_plant_refuses"
    ),
    ". /opt/ros/jazzy/setup.sh": "no ROS install here: the PyPI wheels in .venv stand in",
    'predictive-drive run im_short --external "torque_controller=python3 '
    'examples/dtc_im/dtc_im/dtc_node.py"': "the README's (shortened here)",
    "python test/live_bench.py": "a benchmark: it prints figures, asserts none",
    "predictive-drive run": "a name, not a command",
    # docs/recordings.md
    "predictive-drive report bags/<run>": "test_every_verb_runs_from_the_install",
    "predictive-drive report bags/<run> --figures figs/": "test_figures.py",
    "predictive-drive report bags/<run> --window 1,3 --thd-window 2,3": (
        "test_a_thd_window_without_a_whole_cycle_is_a_note_and_report_takes_other_windows"
    ),
    "predictive-drive compare bags/a bags/b --figures figs/": (
        "test_compare_puts_the_example_beside_db_mptc"
    ),
    "predictive-drive analyze bags/<pmsm run>": "test_analysis.py",
    "predictive-drive repair BAG": "test_every_verb_runs_from_the_install",
    "predictive-drive replay BAG": "test_replay.py",
    "predictive-drive layout [--out FILE]": "test_layout_does_not_overwrite_a_file_unless_told",
    "predictive-drive param set player paused false": (
        "test_replay_reaches_an_independent_subscriber_in_order_byte_for_byte"
    ),
    "predictive-drive replay BAG --into torque_controller [--strategy NAME]": (
        "test_replay_into_the_strategy_that_made_it_reproduces_every_command"
    ),
    # docs/reproduction.md: each study, shortened, in test_analysis.py and test_realism.py
    "predictive-drive reproduce SCENARIO": "a form, not a command",
    "predictive-drive reproduce spmsm_analysis": "test_reproduce_spmsm_sweep_shortened",
    "predictive-drive reproduce ipmsm_validation": "test_reproduce_ipmsm_validation_shortened",
    "predictive-drive reproduce ipmsm_mtpa": "test_mtpa_study_shortened_rows_and_claims (on "
    "hs_ipmsm_mtpa: the same study)",
    "predictive-drive reproduce hs_ipmsm_mtpa": "test_mtpa_study_shortened_rows_and_claims",
    "predictive-drive reproduce realism": "test_the_command_prints_every_column_with_its_ranks",
    # docs/physics.md: the studies whose figures the page gives (minutes each)
    "predictive-drive reproduce realism --set plant.speed_window=2.5e-4": (
        "test_a_real_drive_setting_replaces_the_studys_in_its_columns"
    ),
    "predictive-drive sweep im_paper --strategy mptc,db_mptc --set plant.dead_time=0,2e-6 --set "
    "plant.device_drop=0,1.5": "test_real_drive.py (dead time and drops)",
    "predictive-drive sweep ipmsm_validation --strategy mptc --set plant.encoder_lines=2500 --set "
    "plant.speed_window=1e-3": "test_real_drive.py (the encoder)",
    # docs/reproduction.md
    "predictive-drive sweep im_paper --strategy mptc_db,db_mptc --set "
    "torque_controller.a0_form=derived,paper_printed": "test_core_control.py (a0_form)",
    "predictive-drive analyze BAG --write-tables": "test_analysis.py",
    "predictive-drive analyze BAG": "test_analysis.py",
    "predictive-drive reproduce realism [--figures DIR] [--scheduler ADDRESS]": (
        "test_the_figures_draw_the_table, test_the_study_on_a_dask_cluster_equals_the_local_one"
    ),
    # docs/performance.md
    "predictive-drive bench": "test_every_verb_runs_from_the_install (bench --quick)",
    "predictive-drive bench --json": "test_every_verb_runs_from_the_install (bench --quick --json)",
    "python test/writer_bench.py": "a benchmark: it prints figures, asserts none",
    "predictive-drive bench --json --no-ros": (
        "test_every_verb_runs_from_the_install (bench --quick --json); a benchmark"
    ),
    "predictive-drive sweep ipmsm_steady_mpc --strategy direct_mpc --set "
    "torque_controller.horizon=1,3,5,10 --set torque_controller.lambda_u=… --json": (
        "64 runs up to N = 10 (minutes); test_sweep.py runs sweeps with --set and --json"
    ),
    "predictive-drive run im_paper --engine inprocess": "the engine of test_core_metrics.py's "
    "runs; a command of the measurement it names",
    "make run": "the README's (shortened here)",
    "make bench": "test_every_verb_runs_from_the_install (bench --quick)",
    "predictive-drive bench --json --no-ros --no-horizons": "a benchmark: it prints figures, "
    "asserts none; test_every_verb_runs_from_the_install runs bench --quick and reads its "
    "losses row",
    "predictive-drive report BAG --window 50,60": (
        "test_a_thd_window_without_a_whole_cycle_is_a_note_and_report_takes_other_windows"
    ),
    "predictive-drive sweep ipmsm_drive_cycle --strategy mptc,simplified1,simplified2,simplified3 "
    "--set plant.losses.machine=true,false --out DIR --record": "8 runs of the 60 s cycle, 21.5 "
    "min here; test_the_drive_cycle_heats_the_plant_away_from_the_controllers_model runs a "
    "tenth of a second of it",
    "predictive-drive bench --json --graph ros,ros_example_dtc --no-horizons": "a benchmark: "
    "it prints figures, asserts none (test_cli.py refuses its unknown keys)",
    "predictive-drive bench --graph ros,ros_example_dtc": "the command above, printed as text",
    "predictive-drive bench --external torque_controller=COMMAND --label NAME": (
        "test_bench_times_your_controller_beside_ours"
    ),
    # how the timings the pages give were measured (the commands themselves run above)
    "time make run": "the measurement of the README's timing (make run runs here, shortened)",
    "time predictive-drive reproduce SCENARIO": "the measurement of reproduction.md's timings",
    "time predictive-drive reproduce im_paper": "the measurement of the README's timing",
    "predictive-drive run im_paper --strategy db_mptc": "what the README's make run runs",
    "make setup": "the venv of this test's copy is the one make setup made (CI: make test)",
    # names of other tools, not commands
    "ros2 bag info/play": "a name, not a command",
    "ros2 bag play": "a name, not a command",
    "ros2 bag reindex": "a name, not a command",
    "ros2 launch": "a name, not a command",
    "ros2 run": "a name, not a command",
    "predictive-drive layout": "test_every_verb_runs_from_the_install",
    # docs/architecture.md
    "predictive-drive param": "a name, not a command",
    "make test-core": "make test runs the same tests",
}


@dataclass
class Command:
    text: str  #: as the page prints it (a trailing comment dropped)
    output: list[str] = field(default_factory=list)  #: the lines shown under it


def _strip_comment(line: str) -> str:
    return re.split(r"\s{2,}#\s", line, maxsplit=1)[0].strip()


def block_commands(text: str) -> list[Command]:
    """The commands of a page's ```sh and ```console blocks, in order."""
    out: list[Command] = []
    for lang, body in re.findall(r"^```(\w*)\n(.*?)^```", text, re.MULTILINE | re.DOTALL):
        for line in body.splitlines():
            if lang == "sh" and line.strip() and not line.lstrip().startswith("#"):
                out.append(Command(_strip_comment(line)))
            elif lang == "console":
                if line.startswith("$ "):
                    out.append(Command(_strip_comment(line[2:])))
                elif out and line.strip():
                    out[-1].output.append(line.strip())
    return out


#: how an inline command starts (in `backticks` in the prose)
PROGRAMS = (
    "predictive-drive", "make ", "python ", "python3 ", "pip ", "colcon ", "ros2 ", "rosdep ",
    "ROS_DOMAIN_ID=", ". ", "cd ", "time ", "install/predictive_drive/lib/predictive_drive/predictive-drive ",
)  # fmt: skip


def page_commands(text: str) -> list[str]:
    """Every command a page prints: its blocks', and those inline in its prose (a span may wrap
    lines)."""
    found = [c.text for c in block_commands(text)]
    prose = re.sub(r"^```.*?^```", "", text, flags=re.MULTILINE | re.DOTALL)
    for span in re.findall(r"`([^`]+)`", prose):
        span = " ".join(span.split())
        if span.startswith(PROGRAMS):
            found.append(span)
    return list(dict.fromkeys(found))


PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


@pytest.mark.core
def test_every_command_of_the_docs_is_run_or_listed():
    """A command of the README or docs/ is run by test_the_readme_runs_as_printed, or listed in
    NOT_RUN with the test that runs it or why not; NOT_RUN names only commands the pages print."""
    readme = [c.text for c in block_commands((ROOT / "README.md").read_text())]
    printed = {c: p.name for p in PAGES for c in page_commands(p.read_text())}
    unlisted = sorted(f"{p}: {c}" for c, p in printed.items() if c not in readme + [*NOT_RUN])
    assert not unlisted, "run these or list them in NOT_RUN:\n" + "\n".join(unlisted)
    stale = sorted(c for c in NOT_RUN if c not in printed)
    assert not stale, f"NOT_RUN names commands no page prints: {stale}"
    assert all(c in readme for c in [*SHORTENED, *ALONGSIDE]), "SHORTENED/ALONGSIDE: stale"


@pytest.mark.core
def test_the_docs_commands_parse():
    """Every complete `predictive-drive` command of the pages (no placeholder in it) is one the
    command line accepts: a renamed verb or option fails here."""
    from predictive_drive.cli import build_parser

    parser = build_parser()
    bad = []
    for p in PAGES:
        for c in page_commands(p.read_text()):
            words = (
                shlex.split(c.split("predictive-drive", 1)[1]) if "predictive-drive " in c else []
            )
            if not words or any(re.search(r"[A-Z]{2,}|[<\[…]|\.\.\.", w) for w in words):
                continue  # a name or a form with placeholders (BAG, [--figures DIR], <run>)
            if NOT_RUN.get(c, "").startswith("a name"):
                continue
            try:
                with contextlib.redirect_stdout(io.StringIO()):  # --help prints
                    parser.parse_args(words)
            except SystemExit as e:
                if e.code:  # --help exits 0
                    bad.append(f"{p.name}: {c}")
    assert not bad, bad


def fresh_copy(dest: Path) -> Path:
    """The checkout's files as a fresh clone has them (tracked, or new and not ignored), the
    checkout's venv linked in as `make setup` would have made it."""
    r = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        cwd=ROOT, capture_output=True, timeout=60,
    )  # fmt: skip
    if r.returncode == 0:
        for name in r.stdout.decode().split("\0"):
            src = ROOT / name
            if name and src.is_file():
                (dest / name).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(src, dest / name)
    else:  # not a git checkout (an unpacked archive): all but what runs make
        made = ("bags", "build", "install", "log", ".venv", ".git", "__pycache__", "*.egg-info")
        shutil.copytree(ROOT, dest, ignore=shutil.ignore_patterns(*made), dirs_exist_ok=True)
    (dest / ".venv").symlink_to(Path(sys.prefix))
    return dest


def run_in(
    workdir: Path, prelude: list[str], command: str, env: dict[str, str], timeout: float = 300
) -> subprocess.CompletedProcess[str]:
    """``command`` in bash in ``workdir`` after the ``prelude`` lines; it and all it started end
    before this returns."""
    script = "\n".join([*prelude, command])
    p = subprocess.Popen(
        ["bash", "-c", script], cwd=workdir, env=env, text=True, start_new_session=True,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )  # fmt: skip
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        end_all([p])
        out, err = p.communicate()
        raise AssertionError(f"{command}: still running after {timeout} s\n{err[-3000:]}") from None
    finally:
        end_all([p])
    return subprocess.CompletedProcess(script, p.returncode, out, err)


def assert_prints(command: Command, stdout: str) -> None:
    """The README's lines under the command are in its output, in order (``...`` skips)."""
    lines = [line.strip() for line in stdout.splitlines()]
    at = 0
    for want in command.output:
        if want in ("...", "…"):
            continue
        try:
            at = lines.index(want, at) + 1
        except ValueError:
            raise AssertionError(
                f"{command.text}: the README shows {want!r}, which it does not print:\n{stdout}"
            ) from None


@pytest.mark.process
def test_the_readme_runs_as_printed(tmp_path):
    if not (Path(sys.prefix) / "bin" / "activate").is_file():
        pytest.skip("not run from a venv: the README's commands need the checkout's")
    work = fresh_copy(tmp_path / "checkout")
    env = clean_env()
    env.setdefault("ROS_DOMAIN_ID", os.environ.get("ROS_DOMAIN_ID", "0"))
    prelude: list[str] = []
    beside: subprocess.Popen[str] | None = None
    beside_log = tmp_path / "beside.log"
    n = None
    try:
        for c in block_commands((ROOT / "README.md").read_text()):
            if c.text in NOT_RUN and c.text not in SHORTENED:
                continue
            if c.text.startswith((". ", "source ", "export ")):  # the shell's environment
                r = run_in(work, prelude, c.text, env)
                assert r.returncode == 0, f"{c.text}: exit {r.returncode}\n{r.stderr}"
                prelude.append(c.text)
                continue
            command, shortened = (SHORTENED[c.text][0], True) if c.text in SHORTENED else (
                c.text, False
            )  # fmt: skip
            if n is not None:  # the command of the second shell
                command = re.sub(r"\bN\b", n, command)
            if c.text in ALONGSIDE:
                beside, n = _start_beside(
                    work, prelude, command, env, beside_log, ALONGSIDE[c.text]
                )
                continue
            t0 = time.monotonic()
            r = run_in(work, prelude, command, env)
            took = time.monotonic() - t0
            print(f"{took:6.1f} s  {command}")  # where the test's time goes (pytest -s)
            assert r.returncode == 0, f"{command}: exit {r.returncode} after {took:.0f} s\n" + (
                f"{r.stdout[-2000:]}\n{r.stderr[-3000:]}"
            )
            if not shortened:
                assert_prints(c, r.stdout)
            if beside is not None:  # the first shell's run ends on its own, having taken it
                assert beside.wait(timeout=300) == 0, beside_log.read_text()[-3000:]
                beside, n = None, None
    finally:
        if beside is not None:
            end_all([beside])


def _start_beside(
    work: Path, prelude: list[str], command: str, env: dict[str, str], log: Path, ready: str
) -> tuple[subprocess.Popen[str], str]:
    """``command`` started as from a first shell; returns it once its stderr has said
    ``ready``, with what the pattern's group found (the N the second shell uses)."""
    with log.open("w") as f:
        p = subprocess.Popen(
            ["bash", "-c", "\n".join([*prelude, command])], cwd=work, env=env, text=True,
            stdout=f, stderr=subprocess.STDOUT, start_new_session=True,
        )  # fmt: skip
    deadline = time.monotonic() + 120
    while not (m := re.search(ready, log.read_text())):
        if p.poll() is not None or time.monotonic() > deadline:
            end_all([p])
            raise AssertionError(f"{command}: never said {ready!r}\n{log.read_text()[-3000:]}")
        time.sleep(0.1)
    return p, m.group(1)
