"""Study checkpoints (``jaxarm.io.checkpoints``): an interrupted study resumes from its saved
chunks to the same bits and the same CSV, byte for byte; a checkpoint of another study is
refused with one line naming what differs."""

import logging
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import jaxarm
from jaxarm import cli, study
from jaxarm.optim import restarts

SIZES = dict(n_particles=5, n_iters=7)
CLI_SIZES = ("--particles", "5", "--iters", "7", "--collision", "sampled")  # as SIZES on case2


def _interrupt_after(monkeypatch, chunks: int) -> list:
    """``run_restarts`` raises KeyboardInterrupt (as Ctrl-C would) on its call after
    ``chunks`` calls; returns the list of the ``first_restart`` each call asked for."""
    calls, run = [], restarts.run_restarts

    def counted(*args, **kwargs):
        calls.append(kwargs["first_restart"])
        if len(calls) > chunks:
            raise KeyboardInterrupt
        return run(*args, **kwargs)

    monkeypatch.setattr(study, "run_restarts", counted)
    return calls


def test_an_interrupted_study_resumes_to_the_same_csv(case2, tmp_path, monkeypatch):
    methods = ["A", "B:feasibility"]
    whole = study.escape_study(case2, methods, n_restarts=9, chunk_size=4, **SIZES)
    calls = _interrupt_after(monkeypatch, chunks=1)
    with pytest.raises(KeyboardInterrupt):
        study.escape_study(case2, methods, n_restarts=9, chunk_size=4, checkpoint=tmp_path,
                           **SIZES)
    assert calls == [0, 3]  # three chunks of 3 (equal lengths): the first saved, then Ctrl-C
    assert sorted(p.name for p in tmp_path.glob("*.npz")) == ["method0-restarts0000000-0000003.npz"]
    calls = _interrupt_after(monkeypatch, chunks=100)
    resumed = study.escape_study(case2, methods, n_restarts=9, chunk_size=4, checkpoint=tmp_path,
                                 **SIZES)
    assert calls == [3, 6, 0, 3, 6]  # A from restart 3 on, then all of B
    assert resumed.to_csv() == whole.to_csv()
    for a, b in zip(resumed.methods, whole.methods):
        for mine, theirs in zip(a.outcome, b.outcome):
            np.testing.assert_array_equal(mine, theirs)
    calls.clear()  # a finished checkpoint: the same call again runs nothing
    assert study.escape_study(case2, methods, n_restarts=9, chunk_size=4, checkpoint=tmp_path,
                              **SIZES).to_csv() == whole.to_csv()
    assert calls == []


def test_another_chunk_size_or_more_restarts_resume_it_too(case2, tmp_path, monkeypatch):
    study.escape_study(case2, ["A"], n_restarts=5, chunk_size=5, checkpoint=tmp_path, **SIZES)
    calls = _interrupt_after(monkeypatch, chunks=100)
    more = study.escape_study(case2, ["A"], n_restarts=8, chunk_size=2, checkpoint=tmp_path,
                              **SIZES)
    assert calls == [5, 7]  # the saved five reused, the other three run
    whole = study.escape_study(case2, ["A"], n_restarts=8, chunk_size=8, **SIZES)
    assert more.to_csv() == whole.to_csv()
    fewer = study.escape_study(case2, ["A"], n_restarts=3, checkpoint=tmp_path, **SIZES)
    assert fewer.to_csv() == study.escape_study(case2, ["A"], n_restarts=3, **SIZES).to_csv()


@pytest.mark.parametrize("change, message", [
    (dict(problem="paper-case-1"), r"problem 'paper-case-2', not 'paper-case-1'"),
    (dict(methods=["A", "C"]), r"methods 'A,B', not 'A,C'"),
    (dict(methods=["A", "B[social_coeff=2]"]), r"methods 'A,B', not 'A,B\[social_coeff=2\]'"),
    (dict(seed=3), r"base seed 0, not 3"),
    (dict(n_iters=8), r"iterations 7, not 8"),
    (dict(n_particles=6), r"swarm size 5, not 6"),
    (dict(margin=0.5), r"another version of the problem of that name"),
])
def test_a_checkpoint_of_another_study_is_refused_naming_what_differs(case2, tmp_path, change,
                                                                     message):
    settings = dict(problem="paper-case-2", methods=["A", "B"], seed=0) | SIZES
    study.escape_study(case2, settings["methods"], n_restarts=2, checkpoint=tmp_path, **SIZES)
    settings |= change
    problem = jaxarm.load_scenario(settings.pop("problem"), collision="sampled")
    if "margin" in settings:
        problem = problem.replace(margin=settings.pop("margin"))
    with pytest.raises(ValueError, match=f"checkpoint '{tmp_path}' was written for {message}: "
                                         "give another folder, or remove this one"):
        study.escape_study(problem, settings.pop("methods"), n_restarts=2, checkpoint=tmp_path,
                           **settings)


def test_an_optimiser_of_other_settings_is_another_method(case2, tmp_path):
    from test_custom import FrozenES

    study.escape_study(case2, [FrozenES()], n_restarts=2, n_iters=3, checkpoint=tmp_path)
    with pytest.raises(ValueError, match="the same methods with other settings"):
        study.escape_study(case2, [FrozenES(population=6)], n_restarts=2, n_iters=3,
                           checkpoint=tmp_path)


def test_a_folder_that_is_no_checkpoint_or_a_broken_chunk_is_named(case2, tmp_path):
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match=r"holds files but no study.json: not a study checkpoint"):
        study.escape_study(case2, ["A"], n_restarts=2, checkpoint=tmp_path, **SIZES)
    folder = tmp_path / "new" / "deeper"  # created with its parents
    study.escape_study(case2, ["A"], n_restarts=2, checkpoint=folder, **SIZES)
    (chunk,) = folder.glob("*.npz")
    whole = chunk.read_bytes()
    for broken in (b"not a numpy file", whole[:len(whole) // 2]):  # the second: a cut zip
        chunk.write_bytes(broken)
        with pytest.raises(ValueError, match=rf"cannot read {chunk.name}: .*remove that file"):
            study.escape_study(case2, ["A"], n_restarts=2, checkpoint=folder, **SIZES)
    (folder / "study.json").write_text("{}")
    with pytest.raises(ValueError, match="study.json is not a jaxarm study checkpoint"):
        study.escape_study(case2, ["A"], n_restarts=2, checkpoint=folder, **SIZES)
    for wrong in ("", 3):
        with pytest.raises(ValueError, match=f"checkpoint must be a folder's path, got {wrong!r}"):
            study.escape_study(case2, ["A"], n_restarts=2, checkpoint=wrong, **SIZES)
    with pytest.raises(ValueError, match=r"checkpoint '.*notes.txt' is a file, not a folder"):
        study.escape_study(case2, ["A"], n_restarts=2, checkpoint=tmp_path / "notes.txt",
                           **SIZES)


def test_without_a_bar_each_chunk_logs_the_time_left(case2, caplog):
    with caplog.at_level(logging.INFO, logger="jaxarm.study"):
        study.escape_study(case2, ["A", "C"], n_restarts=6, chunk_size=3, progress=False,
                           **SIZES)
    lines = [r.getMessage() for r in caplog.records if r.name == "jaxarm.study"]
    assert lines[0].startswith("paper-case-2: 3 of 12 seeds of 2 methods (A running), about ")
    assert "left" in lines[0]
    assert lines[-1] == "paper-case-2: 12 of 12 seeds of 2 methods (C done), done"
    assert len(lines) == 4
    assert study._duration(3725) == "1 h 02 min" and study._duration(200.4) == "3 min 20 s"


def test_the_cli_study_resumes_from_its_checkpoint_byte_for_byte(capsys, tmp_path, monkeypatch):
    argv = ["study", "paper-case-2", *CLI_SIZES, "--restarts", "6", "--chunk-size", "3",
            "--methods", "A,C"]
    assert cli.main([*argv, "--csv", str(tmp_path / "whole.csv")]) == 0
    saved = tmp_path / "saved"
    resume = [*argv, "--checkpoint", str(saved), "--csv", str(tmp_path / "resumed.csv")]
    _interrupt_after(monkeypatch, chunks=1)
    assert cli.main(resume) == 130
    err = capsys.readouterr().err
    assert err.splitlines()[-1] == (f"jaxarm: interrupted; the finished chunks are saved in "
                                    f"'{saved}': the same command resumes from them")
    assert not (tmp_path / "resumed.csv").exists()
    monkeypatch.undo()
    assert cli.main(resume) == 0
    assert "jaxarm: paper-case-2: resuming from the checkpoint, 3 of 12 seeds saved" in (
        capsys.readouterr().err)
    assert (tmp_path / "resumed.csv").read_bytes() == (tmp_path / "whole.csv").read_bytes()
    assert cli.main([*argv, "--checkpoint", str(saved), "--seed", "1"]) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"jaxarm: error: checkpoint '{saved}' was written for base seed 0, not 1: give another "
        "folder, or remove this one to start again"]


@pytest.mark.slow
def test_ctrl_c_on_the_command_keeps_what_finished(tmp_path):
    """The real thing: SIGINT to a ``jaxarm study`` process once its first chunk is saved."""
    argv = [sys.executable, "-m", "jaxarm", "study", "paper-case-2", *CLI_SIZES, "--restarts",
            "40", "--chunk-size", "2", "--methods", "A", "--checkpoint", str(tmp_path / "c")]
    process = subprocess.Popen([*argv, "--csv", str(tmp_path / "resumed.csv")],
                               stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 300
    while not list((tmp_path / "c").glob("*.npz")) and time.monotonic() < deadline:
        time.sleep(0.05)
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=300)
    saved = len(list((tmp_path / "c").glob("*.npz")))
    if process.returncode == 0:  # it finished before the signal landed: nothing to resume
        pytest.skip("the study finished before Ctrl-C")
    assert process.returncode == 130 and "the same command resumes from them" in err
    assert 1 <= saved < 20
    subprocess.run([*argv, "--csv", str(tmp_path / "resumed.csv")], check=True,
                   capture_output=True)
    subprocess.run([*argv[:-2], "--csv", str(tmp_path / "whole.csv")], check=True,
                   capture_output=True)
    assert (tmp_path / "resumed.csv").read_bytes() == (tmp_path / "whole.csv").read_bytes()
