"""``reproduce-paper`` (``jaxarm.reproduce``): every table of the report."""

import pytest

from jaxarm import cli


def run_cli(capsys, *argv):
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.slow
def test_cli_reproduce_paper_writes_a_report_with_every_table(capsys, tmp_path):
    code, out, _ = run_cli(capsys, "reproduce-paper", "--out", str(tmp_path), "--seeds", "8",
                           "--suite", "paper-case-2,open-space", "--suite-seeds", "4",
                           "--degrees", "6")
    assert code == 0 and "report written" in out
    report = (tmp_path / "report.md").read_text()
    for heading in ("Table 2", "Escape probability", "Table 3", "Tables 4 and 5", "Table 6",
                    "shipped suite", "reconstructed"):
        assert heading in report
    for image in ("case1_escape_rates.png", "case1_motion.png", "suite_escape_rates.png"):
        assert f"]({image})" in report and (tmp_path / image).stat().st_size > 5000
    assert len((tmp_path / "case1_study.csv").read_text().splitlines()) == 1 + 6 * 8
