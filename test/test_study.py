"""What every study of `reproduce` gets from api/study.py, whatever its table: progress counted
across all its sweeps (a bar on a terminal, a line per finished run elsewhere), its bags kept
only when asked (else recorded where it needs them and removed), and the metrics window its
runs actually used."""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

import pytest

from predictive_drive import cli
from predictive_drive.api.reproduce import reproduce
from predictive_drive.api.study import studying
from predictive_drive.api.sweep import Case

pytestmark = pytest.mark.core


def test_a_study_counts_its_runs_across_its_sweeps(tmp_path, monkeypatch):
    """Two sweeps of one study: the planned total grows as each starts, the count goes on; the
    windows are the runs' own; nothing is recorded that nobody needs, and the temporary folder
    goes when the study ends."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    told = []
    with studying(None, duration=0.08, jobs=2, progress=lambda k, n: told.append((k, n))) as s:
        first = s.runs("im_short", [Case("mptc"), Case("db_mptc")])
        second = s.runs("ipmsm_short", [Case(x) for x in ("mptc", "simplified1", "simplified2")])
        assert s.folder.is_dir() and not list(s.folder.iterdir())  # no bag asked for or needed
        assert s.bag("a_case") is None and s.bag("b_case", needed=True) is not None
    assert told == [(1, 2), (2, 2), (3, 5), (4, 5), (5, 5)]
    assert [r.strategy for r in first + second] == [
        "mptc", "db_mptc", "mptc", "simplified1", "simplified2"
    ]  # fmt: skip
    assert s.windows == {
        "im_short": [(0.05, pytest.approx(0.08))],
        "ipmsm_short": [(0.0, pytest.approx(0.08))],
    }
    assert not list(tmp_path.glob("predictive_drive_study_*"))  # the temporary folder is gone


def test_reproduce_says_what_it_does_and_keeps_bags_only_when_asked(capsys, tmp_path, monkeypatch):
    """Not on a terminal: a line per finished run on stderr; the shortened window said; no bag
    left anywhere. With --bags DIR: the bags there, and how many and how large."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    assert cli.main(["reproduce", "im_paper", "--duration", "0.06"]) == 0
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert [line.split(" (")[0] for line in lines] == [
        f"reproduce im_paper: run {k} of 3 done" for k in (1, 2, 3)
    ]
    assert (
        "NOTE: runs shortened to 0.06 s, so the figures are over the window 0.05-0.06 s, not the "
        "paper's; not comparable with the paper"
    ) in out
    assert "bags" not in out
    # the window used, everywhere (was: 'window 0.05-6 s' in the header, 'over 0.05-6 s' below)
    assert "Table 2, window 0.05-0.06 s (the paper's: 0.05-6 s)" in out
    assert "against the reference in force at k over 0.05-0.06 s (the paper's: 0.05-6 s);" in out
    assert "0.05-6 s;" not in out
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tmp"]
    assert not list((tmp_path / "tmp").glob("predictive_drive_study_*"))

    assert (
        cli.main(["reproduce", "im_paper", "--duration", "0.06", "--bags", "kept", "--json"]) == 0
    )
    out, err = capsys.readouterr()
    d = json.loads(out)
    assert err == ""  # --json: quiet
    made = sorted((tmp_path / "kept").iterdir())
    assert len(made) == 3 and all((b / "metadata.yaml").is_file() for b in made)
    size = sum(f.stat().st_size for b in made for f in b.rglob("*") if f.is_file())
    assert d["bags"] == {"folder": "kept", "count": 3, "bytes": size}
    assert sorted(Path(r["bag"]) for r in d["rows"]) == [b.resolve() for b in made]
    assert d["windows"] == {"im_paper": [[0.05, pytest.approx(0.06)]]}


def test_a_study_that_times_its_runs_needs_no_bags_kept(tmp_path, monkeypatch):
    """ipmsm_validation replays each run's decisions for its compute ratios: it records them to
    the temporary folder, and its rows name no bag once that is gone."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    d = reproduce("ipmsm_validation", duration=0.05, repeats=1)
    assert all(r.replay_identical and r.bag is None for r in d.rows)
    assert d.bags is None and not list(tmp_path.glob("predictive_drive_study_*"))


def test_on_a_terminal_the_progress_is_a_bar(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    assert cli.main(["sweep", "im_short", "--strategy", "mptc,db_mptc", "--duration", "0.01"]) == 0
    err = capsys.readouterr().err
    assert "run/s" in err and "done (" not in err  # tqdm's bar, not the lines of a log


def test_a_ctrl_c_says_which_runs_finished_and_which_bags_it_cut(tmp_path):
    """Interrupted while runs are in flight (here right after the first, short one finished):
    the study says how many of its runs had finished, where their bags are, and each bag it
    cut, as a sweep lists them (was: 'error: interrupted' alone, the cut bags in --bags DIR
    unnamed)."""
    from predictive_drive.errors import Interrupted
    from procs import wait_until

    def progress(done, total):  # once a long run is in flight (its bag begun)
        wait_until(lambda: len(list(kept.glob("long*"))) > 0, "no long run began", timeout=60)
        raise KeyboardInterrupt

    kept = tmp_path / "kept"
    with studying(kept, jobs=2, progress=progress) as s:
        cases = [Case("db_mptc", bag=s.bag("short"), duration=0.01)] + [
            Case("db_mptc", {"torque_controller.lambda_psi": v}, bag=s.bag(f"long{v}"),
                 duration=60.0)
            for v in (10, 20)
        ]  # fmt: skip
        with pytest.raises(Interrupted) as e:
            s.runs("im_short", cases)
    said = str(e.value).splitlines()
    assert (
        said[0] == f"interrupted: 1 of 3 runs of the study had finished; their bags are in {kept}"
    )
    cut = [line for line in said[1:] if line.startswith("not complete: ")]
    assert cut and len(cut) == len(said) - 1, said
    assert all(
        "cut at" in line and "closed (readable)" in line or "removed" in line for line in cut
    )


def test_a_ctrl_c_between_sweeps_says_how_many_runs_had_finished(tmp_path, monkeypatch):
    """Between two sweeps of a study (here right after the first): the same summary as inside
    one, not 'error: interrupted' alone; the temporary folder goes all the same."""
    from predictive_drive.errors import Interrupted

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    with pytest.raises(Interrupted, match=r"^interrupted: 2 of 2 runs of the study had finished "
                       r"\(no table: it needs every run; --bags DIR keeps each run's bag\)$"):  # fmt: skip
        with studying(None, duration=0.02, jobs=2) as s:
            s.runs("im_short", [Case("mptc"), Case("db_mptc")])
            raise KeyboardInterrupt
    assert not list(tmp_path.glob("predictive_drive_study_*"))
