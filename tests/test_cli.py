"""The ``jaxarm`` command (``jaxarm.cli``)."""

import gzip
import json
import os
import pathlib

import numpy as np
import pytest
import tomli_w

import jaxarm
from jaxarm import choices, cli
from jaxarm.choices import DEFAULT_CONSTRAINT, DEFAULT_METHODS, DEFAULT_RESTARTS, MAX_DEGREE

# The search sizes of every solve and study test here: with them (and restart counts in one
# padded block) they run one compiled search program.
SEARCH_SIZES = ("--particles", "6", "--iters", "10", "--samples", "51")


def run_cli(capsys, *argv):
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_scenarios_lists_every_shipped_scenario(capsys):
    code, out, _ = run_cli(capsys, "scenarios")
    assert code == 0
    assert len(out.splitlines()) == len(jaxarm.available_scenarios()) >= 11


def test_cli_solve_writes_json_and_plot(capsys, tmp_path):
    method = "A-ring[inertia_end=0.4]"  # a named method with a field changed
    code, out, _ = run_cli(capsys, "solve", "paper-case-2", *SEARCH_SIZES, "--restarts", "2",
                           "--method", method, "--json", str(tmp_path / "r.json"),
                           "--plot", str(tmp_path / "r.png"))
    assert code == 0 and "fitness" in out
    data = json.loads((tmp_path / "r.json").read_text())
    assert len(data["result"]["best_x"]) == 3 and len(data["result"]["history"]) == 11
    assert data["scenario"] == "paper-case-2" and data["method"] == method
    loaded = jaxarm.Result.from_dict(data["result"])
    assert loaded.restarts.best_x.shape == (2, 3) and loaded.method == method
    assert loaded.config == jaxarm.PRESETS["A"]._replace(topology="ring", inertia_end=0.4)
    saved = jaxarm.load_run(tmp_path / "r.json")  # the name alone repeats the run
    again = jaxarm.solve(saved.problem, saved.method, **saved.settings)
    np.testing.assert_array_equal(again.restarts.best_x, loaded.restarts.best_x)
    assert (tmp_path / "r.png").stat().st_size > 5000


def test_cli_solve_without_a_method_runs_the_default_search_and_says_so(capsys, tmp_path):
    code, out, _ = run_cli(capsys, "solve", "paper-case-2", *SEARCH_SIZES, "--json",
                           str(tmp_path / "r.json"))
    assert code == 0
    assert f"{2 * DEFAULT_RESTARTS} restart(s) x 6 particles" in out
    ring, preset = DEFAULT_METHODS
    assert (f"method {ring} x {DEFAULT_RESTARTS} + {preset} x {DEFAULT_RESTARTS} (inertia), "
            f"constraint {DEFAULT_CONSTRAINT}") in out
    saved = jaxarm.load_run(tmp_path / "r.json")  # the record repeats the default search
    assert saved.method is None
    again = jaxarm.solve(saved.problem, saved.method, **saved.settings)
    np.testing.assert_array_equal(again.restarts.best_x, saved.result.restarts.best_x)
    code, out, _ = run_cli(capsys, "solve", "paper-case-2", *SEARCH_SIZES, "--method", "A")
    assert code == 0 and "1 restart(s) x 6 particles" in out and "constraint death" in out


def test_cli_solve_json_describes_its_run_well_enough_to_repeat_it(capsys, tmp_path):
    code, _, _ = run_cli(capsys, "solve", "paper-case-2", *SEARCH_SIZES, "--restarts", "3",
                         "--seed", "4", "--init-low", "-60", "--init-high", "80", "--refine",
                         "all", "--constraint", "feasibility", "--json", str(tmp_path / "r.json"))
    assert code == 0
    data = json.loads((tmp_path / "r.json").read_text())
    assert data["jaxarm"] == jaxarm.__version__ and data["jax"]
    assert data["settings"] == dict(n_particles=6, n_iters=10, n_restarts=3, seed=4,
                                    constraint="feasibility", refine="all", improve=False,
                                    time_limit=None, max_stages=1)  # the stages that ran
    scenario = tmp_path / "again.toml"
    scenario.write_text(tomli_w.dumps(data["problem"]))
    problem = jaxarm.load_scenario(scenario)
    assert problem == jaxarm.load_scenario("paper-case-2", n_samples=51, init_low=-60.0,
                                           init_high=80.0)
    again = jaxarm.solve(problem, data["method"], **data["settings"])
    np.testing.assert_array_equal(again.restarts.best_x,
                                  jaxarm.Result.from_dict(data["result"]).restarts.best_x)
    saved = jaxarm.load_run(tmp_path / "r.json")  # the same, in one call
    assert saved.problem == problem and saved.versions["jaxarm"] == jaxarm.__version__
    repeated = jaxarm.solve(saved.problem, saved.method, **saved.settings)
    np.testing.assert_array_equal(repeated.restarts.best_x, saved.result.restarts.best_x)
    np.testing.assert_array_equal(
        jaxarm.Result.from_json((tmp_path / "r.json").read_text()).restarts.history,
        saved.result.restarts.history)
    with pytest.raises(ValueError, match="not a solve --json record"):
        scenario.write_text(json.dumps({"result": data["result"]}))
        jaxarm.load_run(scenario)


def test_load_run_names_the_file_it_cannot_read(tmp_path):
    (tmp_path / "notes.txt").write_text("not JSON")
    with pytest.raises(ValueError, match=r"notes.txt is not a solve --json record: not JSON"):
        jaxarm.load_run(tmp_path / "notes.txt")
    with pytest.raises(ValueError, match=r"cannot read '.*missing.json': No such file"):
        jaxarm.load_run(tmp_path / "missing.json")
    (tmp_path / "list.json").write_text("[1, 2]")
    with pytest.raises(ValueError, match=r"list.json is not a solve --json record: no \['method'"):
        jaxarm.load_run(tmp_path / "list.json")


def test_cli_solve_times_the_best_path_and_exports_it(capsys, tmp_path):
    sizes = (*SEARCH_SIZES, "--restarts", "2")
    code, out, _ = run_cli(capsys, "solve", "paper-case-2", *sizes, "--max-velocity", "1",
                           "--max-torque", "40,20,5", "--export", str(tmp_path / "t.csv"),
                           "--json", str(tmp_path / "r.json"))
    assert code == 0
    best_x = json.loads((tmp_path / "r.json").read_text())["result"]["best_x"]
    problem = jaxarm.load_scenario("paper-case-2", n_samples=51)  # the problem solved
    duration = jaxarm.min_duration(problem, best_x, max_velocity=1.0,  # as the CLI times it
                                   max_torque=[40.0, 20.0, 5.0], allow_colliding=True)
    assert f"trajectory: T = {duration:.6g} s (the shortest meeting max_velocity" in out
    assert "peak |velocity| [1.0," in out or ", 1.0" in out.split("peak |velocity|")[1]
    rows = np.loadtxt(tmp_path / "t.csv", delimiter=",", skiprows=1)
    assert rows[-1, 0] == pytest.approx(duration) and rows.shape[1] == 13
    code, out, _ = run_cli(capsys, "solve", "paper-case-2", *sizes, "--duration", "2.5",
                           "--export", str(tmp_path / "t.json"))
    assert code == 0 and "trajectory: T = 2.5 s (given)" in out
    assert json.loads((tmp_path / "t.json").read_text())["duration"] == 2.5
    code, out, _ = run_cli(capsys, "solve", "paper-case-2", *sizes, "--duration", "2.5",
                           "--export", str(tmp_path / "t.csv.gz"))  # compressed, by its name
    assert code == 0
    with gzip.open(tmp_path / "t.csv.gz", "rt") as compressed:
        assert np.loadtxt(compressed, delimiter=",", skiprows=1)[-1, 0] == 2.5


def test_cli_study_writes_json_csv_and_plot(capsys, tmp_path):
    code, out, _ = run_cli(capsys, "study", "paper-case-2", *SEARCH_SIZES, "--restarts", "4",
                           "--methods", "A,A:epsilon,A[social_coeff=2,inertia_end=0.5]",
                           "--pairwise",
                           "--json", str(tmp_path / "s.json"), "--csv", str(tmp_path / "s.csv"),
                           "--plot", str(tmp_path / "s.png"))
    assert code == 0 and "escape rate" in out and "| A:epsilon - A | " in out
    assert "| McNemar p |" in out
    assert "| A[social_coeff=2,inertia_end=0.5] | death |" in out  # its comma kept inside
    assert len((tmp_path / "s.csv").read_text().splitlines()) == 13
    assert len(json.loads((tmp_path / "s.json").read_text())["methods"]) == 3
    assert (tmp_path / "s.png").stat().st_size > 5000


@pytest.mark.parametrize(
    "argv, message",
    [
        (["solve", "no-such-scenario"], "unknown scenario 'no-such-scenario'"),
        (["solve", "missing.toml"], "cannot read scenario file 'missing.toml'"),
        (["solve", "paper-case-2", "--degree", "4"], "degree must be >= 6, got 4"),
        (["study", "paper-case-2", "--methods", "A,Z"], "--methods must be one of"),
        (["solve", "paper-case-2", "--method", "Z"], "--method must be one of"),
        (["study", "paper-case-2", "--methods", "A,A[foo=1]"], "must be FIELD=VALUE"),
        (["solve", "paper-case-2", "--method", "A-ring[inertia_end=x]"],
         "inertia_end must be a number, got 'x'"),
        (["solve", "paper-case-2", "--method", "A[inertia_end=nan]"],
         "--method 'A[inertia_end=nan]': inertia_end must be a finite number >= 0, got nan"),
        (["solve", "paper-case-2", "--method", "A:feasibility", "--constraint", "death"],
         "method 'A:feasibility' names constraint 'feasibility' but constraint='death'"),
        (["solve", "paper-case-2", "--method", "A:nope"], "constraint must be one of"),
        (["study", "paper-case-2", "--methods", "A,A"], "unique labels, got 'A' twice"),
        (["solve", "paper-case-2", "--samples", "50"], "--samples: n_samples must be odd"),
        (["solve", "paper-case-2", "--init-low", "200"],
         "--init-low: init_low must be < init_high"),
        (["study", "paper-case-2", "--methods", ""], "--methods must be comma-separated names"),
        (["study", "paper-case-2", "--methods", "A,"], "--methods must be comma-separated"),
        (["solve", "paper-case-2", "--plot", "noext"],
         "--plot must end in .png, .pdf, .svg, got 'noext'"),
        (["solve", "paper-case-2", "--plot", "out.xyz"], "--plot must end in .png"),
        (["solve", "paper-case-2", "--gif", "anim.png"], "--gif must end in .gif, got 'anim.png'"),
        (["solve", "paper-case-2", "--gif", "missing/anim.gif"],
         "--gif 'missing/anim.gif': folder 'missing' does not exist"),
        (["study", "paper-case-2", "--json", "missing/s.json"], "folder 'missing' does not exist"),
        (["study", "paper-case-2", "--csv", "missing/s.csv"], "folder 'missing' does not exist"),
        (["reproduce-paper", "--suite", "open-space,nope"], "--suite: unknown scenario 'nope'"),
        (["solve", "paper-case-2", "--duration", "-1"], "--duration must be > 0, got -1.0"),
        (["solve", "paper-case-2", "--duration", "inf"], "--duration must be finite, got inf"),
        (["solve", "paper-case-2", "--duration", "2", "--max-velocity", "1"],
         "give --duration or --max-* limits, not both"),
        (["solve", "paper-case-2", "--max-velocity", "1,2"],
         "--max-velocity: max_velocity must have 3 values, got 2"),
        (["solve", "paper-case-2", "--max-jerk", "0"], "--max-jerk: max_jerk[0] must be > 0"),
        (["solve", "paper-case-2", "--max-torque", "20,50,50"],
         "--max-torque: max_torque[0] = 20 N m is at or below joint 1's static gravity load"),
        (["solve", "open-space", "--max-torque", "20"],
         "--max-torque: the arm of scenario 'open-space' has no link masses ([arm] masses"),
        (["solve", "paper-case-2", "--export", "t.csv"], "--export needs --duration or a --max-"),
        (["solve", "paper-case-2", "--duration", "1", "--export", "t.txt"],
         "--export must end in .csv, .csv.gz, .json, got 't.txt'"),
        (["solve", "paper-case-2", "--duration", "1", "--rate", "0", "--export", "t.csv"],
         "--rate must be > 0, got 0.0"),
        (["--coordinator", "127.0.0.1:1", "solve", "paper-case-2"],
         "--coordinator, --num-processes and --process-id go together"),
        (["--coordinator", "127.0.0.1:1", "--num-processes", "2", "--process-id", "2", "solve",
          "paper-case-2"], r"--process-id must be in [0, 2), got 2"),
        (["solve", "paper-case-2", "--degree", str(MAX_DEGREE + 1)],
         f"--degree: degree must be <= {MAX_DEGREE}, got {MAX_DEGREE + 1}"),
        (["solve", "paper-case-2", "--init-low", "10", "--init-high", "-10"],
         "--init-low, --init-high: init_low must be < init_high, got 10.0 and -10.0\n"),
        (["solve", "paper-case-2", "--init-high", "1e20"],
         "--init-high: init_high must be within +-10000"),
        (["solve", "paper-case-2", "--margin", "1e300"],
         "--margin: margin must be within +-100000 cm"),
        (["solve", "paper-case-2", "--rate", "50"],
         "--rate sets the samples per second of --export; give --export too"),
        (["solve", "paper-case-2", "--duration", "1e-9", "--export", "t.csv"],
         "--duration must be at least 1e-06 s, got 1e-09"),
        (["solve", "paper-case-2", "--duration", "1e6", "--rate", "1e6", "--export", "t.csv"],
         "--rate: rate 1e+06 Hz over 1e+06 s gives 1e+12 rows; at most 1e+07"),
        (["solve", "paper-case-2", "--method", "evosax"],
         "method 'evosax': an evosax strategy is named evosax:<Strategy>, such as evosax:CMA_ES"),
        (["solve", "paper-case-2", "--json", "."], "--json '.' is a folder; give a file name"),
        (["reproduce-paper", "--out", "a-file"], "--out 'a-file' is a file, not a folder"),
        (["solve", "paper-case-2", "--particles", str(10**9)],
         "8 restart(s) x 1000000000 particles is 8e+09 at once, more than 4194304 (2**22)"),
        (["study", "paper-case-2", "--iters", str(10**9), "--restarts", "1000"],
         "500 restart(s) x 1000000001 iterations (+1) is 5e+11 at once, more than 67108864"),
        (["solve", "paper-case-2", "--samples", "1000001"],
         "--samples: n_samples must be <= 100001, got 1000001"),
        (["reproduce-paper", "--suite", ","], "--suite must be comma-separated scenario names"),
        (["reproduce-paper", "--suite="], "--suite must be comma-separated scenario names, got ''"),
        (["reproduce-paper", "--suite", "open-space,open-space"],
         "--suite must not repeat a scenario, got 'open-space,open-space'"),
        (["reproduce-paper", "--quick", "--suite-restarts", "10"],
         "--suite-restarts 10 needs --suite: a quick report runs no suite"),
        (["solve", ""], "scenario must be a shipped name or a path to a .toml file, got ''"),
        (["reproduce-paper", "--out", "a-file/results"],
         "--out 'a-file/results': 'a-file' is a file, not a folder"),
    ],
)
def test_cli_errors_are_one_line_without_traceback(capsys, monkeypatch, tmp_path, argv,
                                                  message):
    def no_work(*args, **kwargs):
        raise AssertionError("the search started before the input was checked")

    for module, name in (("search", "solve"), ("study", "escape_study"),
                         ("optim.restarts", "run_restarts")):
        monkeypatch.setattr(f"jaxarm.{module}.{name}", no_work)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a-file").write_text("not a folder")
    code, _, err = run_cli(capsys, *argv)
    assert code == 2
    assert err.count("\n") == 1 and message in err and "Traceback" not in err
    assert not (tmp_path / "results").exists()


def test_cli_degree_with_per_coefficient_ranges_names_the_flag(capsys, tmp_path):
    scenario = tmp_path / "ranges.toml"
    scenario.write_text("[arm]\nlengths = [30.0, 30.0, 20.0]\n[start]\njoints = [0, 1, 0]\n"
                        "[goal]\njoints = [1, 0, 0]\n[search]\ninit_low = [-1, -2, -3]\n"
                        "init_high = 5\n")
    code, _, err = run_cli(capsys, "solve", str(scenario), "--degree", "7")
    assert code == 2 and err.count("\n") == 1
    assert ("--degree 7: ranges's init_low has one value per coefficient of degree 6; give "
            "--init-low and --init-high too") in err


def test_cli_version_debug_after_the_subcommand_and_particles(capsys):
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["--version"])
    assert exit_info.value.code == 0
    assert capsys.readouterr().out == f"jaxarm {jaxarm.__version__}\n"
    with pytest.raises(jaxarm.ScenarioError, match="unknown scenario 'nope'"):
        cli.main(["solve", "nope", "--debug"])
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["solve", "paper-case-2", "--particles", "1"])
    assert exit_info.value.code == 2
    assert "--particles: must be >= 2, got 1" in capsys.readouterr().err


def test_cli_reports_malformed_and_colliding_scenarios(capsys, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[arm\n")
    code, _, err = run_cli(capsys, "solve", str(bad))
    assert code == 2 and "malformed TOML" in err and err.count("\n") == 1
    colliding = tmp_path / "colliding.toml"
    colliding.write_text("[arm]\nlengths = [30.0, 30.0, 20.0]\n[start]\njoints = [0, 0, 0]\n"
                         "[goal]\njoints = [1, 0, 0]\n[[obstacles]]\ntype = 'circle'\n"
                         "center = [40, 0]\nradius = 3\n")
    code, _, err = run_cli(capsys, "solve", str(colliding))
    assert code == 2 and "start posture" in err and "link 2 overlaps obstacles[0]" in err


def test_cli_help_on_every_subcommand(capsys):
    for command in ("scenarios", "solve", "study", "reproduce-paper"):
        with pytest.raises(SystemExit) as exit_info:
            cli.main([command, "--help"])
        assert exit_info.value.code == 0
        out = capsys.readouterr().out
        assert "usage: jaxarm" in out and "%%" not in out


def test_the_cli_offers_the_librarys_choices_without_importing_jax():
    import subprocess
    import sys

    script = ("import sys, jaxarm.cli; parser = jaxarm.cli.build_parser(); "
              "assert 'jax' not in sys.modules, 'jax imported'; print('ok')")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=120)
    assert done.stdout.strip() == "ok", done.stderr
    commands = cli.build_parser()._subparsers._group_actions[0].choices
    options = {a.dest: a.choices for a in commands["solve"]._actions if a.choices}
    method = next(a for a in commands["solve"]._actions if a.dest == "method")
    assert "method" not in options and all(name in method.help for name in choices.PSO_METHODS)
    assert options["constraint"] == choices.CONSTRAINTS
    assert options["collision"] == choices.COLLISION_MODES


@pytest.mark.parametrize(
    "argv, message",
    [
        (["solve", "paper-case-2", "--seeds", "0"], "unrecognized arguments: --seeds 0"),
        (["solve", "paper-case-2", "--restarts", "0"], "argument --restarts: must be >= 1, got 0"),
        (["study", "paper-case-2", "--restarts", "0"], "argument --restarts: must be >= 1, got 0"),
        (["solve", "paper-case-2", "--degree", "6.5"], "argument --degree: invalid int value"),
        (["reproduce-paper", "--degrees", f"6,{MAX_DEGREE + 1}"],
         f"argument --degrees: degrees must be <= {MAX_DEGREE}, got '6,{MAX_DEGREE + 1}'"),
        (["reproduce-paper", "--degrees", "6,8,6"],
         "argument --degrees: degrees must not repeat a degree, got '6,8,6'"),
        (["nope"], "argument COMMAND: invalid choice: 'nope'"),
        (["solve", "paper-case-2", "--seed", "-3"],
         "argument --seed: must be an integer in [0, 2**31), got -3"),
        (["clutter", "paper-case-2", "--count", "3", "--seed", "2147483648", "-o", "c.toml"],
         "argument --seed: must be an integer in [0, 2**31), got 2147483648"),
    ],
)
def test_cli_usage_errors_are_one_line_too(capsys, argv, message):
    with pytest.raises(SystemExit) as exit_info:
        cli.main(argv)
    err = capsys.readouterr().err
    assert exit_info.value.code == 2
    assert err.count("\n") == 1 and message in err and "usage:" not in err


def test_cli_reads_negative_numbers_in_any_notation():
    args = cli.build_parser().parse_args(["solve", "x", "--init-low", "-1e4", "--init-high",
                                          "-.5", "--margin", "1E-3"])
    assert (args.init_low, args.init_high, args.margin) == (-1e4, -0.5, 1e-3)


def test_cli_numbers_float32_cannot_hold_are_one_line_naming_the_key(capsys, tmp_path):
    scenario = tmp_path / "huge.toml"
    scenario.write_text("[arm]\nlengths = [1e300, 30.0, 20.0]\n[start]\njoints = [0, 0.5, 0.5]\n"
                        "[goal]\njoints = [1, 0.5, 0.5]\n")
    code, _, err = run_cli(capsys, "solve", str(scenario), "--particles", "2", "--iters", "1")
    assert code == 2 and err.count("\n") == 1, err  # no overflow warnings either
    assert "huge.toml: arm.lengths[0] must be within +-100000 cm" in err and "1e+300" in err


def test_cli_names_the_flag_of_a_missing_evosax(capsys):
    from jaxarm.optim import evosax_adapter

    if evosax_adapter.available():
        pytest.skip("evosax is installed")
    for argv in (["solve", "paper-case-2", "--method", "evosax:CMA_ES"],
                 ["study", "paper-case-2", "--methods", "A,evosax:CMA_ES"],
                 ["solve", "paper-case-2", "--method", "evosax"]):
        code, _, err = run_cli(capsys, *argv)
        assert code == 2 and err.count("\n") == 1
        assert "evosax methods need evosax: pip install 'jaxarm[bench]'" in err, err


def test_cli_interrupted_while_writing_leaves_no_half_written_file(capsys, tmp_path,
                                                                   monkeypatch):
    class Figure:  # Ctrl-C halfway through writing the figure
        def savefig(self, path, dpi):
            pathlib.Path(path).write_bytes(b"half a PNG")
            raise KeyboardInterrupt

    monkeypatch.setattr("jaxarm.plot.plot_escape_rates", lambda study: Figure())
    code, _, err = run_cli(capsys, "study", "paper-case-2", *SEARCH_SIZES, "--restarts", "2",
                           "--methods", "A", "--json", str(tmp_path / "s.json"), "--csv",
                           str(tmp_path / "s.csv"), "--plot", str(tmp_path / "s.png"))
    assert code == 130 and err.splitlines()[-1] == "jaxarm: interrupted"  # after any notices
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.csv", "s.json"]  # whole, no more
    json.loads((tmp_path / "s.json").read_text())


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_cli_refuses_a_read_only_output_folder_before_any_work(capsys, tmp_path):
    folder = tmp_path / "read-only"
    folder.mkdir()
    folder.chmod(0o500)
    try:
        code, _, err = run_cli(capsys, "solve", "paper-case-2", "--json", str(folder / "r.json"))
        assert code == 2 and "--json" in err and "is not writable" in err
        code, _, err = run_cli(capsys, "reproduce-paper", "--out", str(folder / "results"))
        assert code == 2 and "--out" in err and "is not writable" in err
    finally:
        folder.chmod(0o700)


def test_cli_says_on_stderr_when_it_compiles_unless_quiet(capsys):
    """A first call that compiles is not silent (shapes no other test uses, so that this
    process compiles them); ``--quiet`` silences the notices, not the results."""
    small = ["--method", "A", "--restarts", "1", "--iters", "2", "--particles", "4",
             "--collision", "sampled"]
    code, out, err = run_cli(capsys, "solve", "paper-case-2", *small, "--samples", "41")
    assert code == 0 and "fitness" in out
    assert "jaxarm: compiling the search" in err and "jaxarm: compiled the search in" in err
    code, out, err = run_cli(capsys, "--quiet", "solve", "paper-case-2", *small, "--samples", "43")
    assert code == 0 and "fitness" in out and "compil" not in err


def test_output_piped_into_a_reader_that_stops_ends_quietly(tmp_path):
    """``jaxarm ... | head -1``: once the reader has gone, the command stops without an error
    line, with the status of a process that SIGPIPE ended (the file is written). The reader
    here is gone before the command writes (a pipe whose read end is closed)."""
    import subprocess
    import sys

    read, write = os.pipe()
    os.close(read)
    try:
        done = subprocess.run(
            [sys.executable, "-m", "jaxarm", "--quiet", "clutter", "open-space", "--count", "300",
             "--kind", "triangles", "--clear-path", "-o", str(tmp_path / "c.toml")],
            stdout=write, stderr=subprocess.PIPE, text=True, timeout=300)
    finally:
        os.close(write)
    assert done.returncode == 141 and done.stderr == "", done.stderr
    assert (tmp_path / "c.toml").stat().st_size > 0


def test_a_flag_that_breaks_a_posture_names_the_obstacle_as_the_scenario_file_does(capsys):
    assert cli.main(["solve", "paper-case-1", "--margin", "0.5"]) == 2
    error = capsys.readouterr().err
    assert error.startswith("jaxarm: error: --margin: goal posture") and error.count("\n") == 1
    assert "from obstacles[" in error and "circles[" not in error
