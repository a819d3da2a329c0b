"""The command line's own behaviour: plain-text help, every verb listed, and an option that does
not apply in a mode refused with the reason (exit 2) before anything runs."""

from __future__ import annotations

import json

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
    (["run", "im_short", "--engine", "inprocess", "--external", "torque_controller=x"],
     "--external runs your node as a process of its own: --engine ros, not inprocess"),
    (["run", "im_short", "--external", "plant=x"],
     "--external plant: not a node you can replace; one of torque_controller, speed_pi"),
    (["run", "im_short", "--strategy", "mptc", "--external", "torque_controller=x"],
     "so --strategy and --switch do not apply"),
    (["run", "im_short", "--external", "torque_controller= "], "an empty command"),
    (["reproduce", "im_paper", "--scheduler", "tcp://x:1"],
     "--scheduler serves the realism and fronts studies only"),
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
