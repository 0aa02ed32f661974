"""The persistent compilation cache (``jaxarm._compile.cache``): where it lives, on and off."""

import sys

import pytest

from jaxarm._compile import cache


def test_cache_dir_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("JAXARM_CACHE_DIR", str(tmp_path / "mine"))
    assert cache.cache_dir() == tmp_path / "mine"
    for off in ("off", "0", ""):
        monkeypatch.setenv("JAXARM_CACHE_DIR", off)
        assert cache.cache_dir() is None and cache.enable_compilation_cache() is None
    monkeypatch.delenv("JAXARM_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    if sys.platform.startswith("linux"):
        assert cache.cache_dir() == tmp_path / "xdg" / "jaxarm" / "xla"
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(ValueError, match="compilation cache directory .*file/xla"):
        cache.enable_compilation_cache(blocker / "xla")


# The CLI's cache on by default and off with --no-cache, and a second process reading what the
# first wrote, bit for bit: tests/test_traces.py.


def test_an_unwritable_cache_is_a_warning_not_a_failure(capsys, monkeypatch, tmp_path):
    from jaxarm import cli

    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv("JAXARM_CACHE_DIR", str(blocker / "xla"))
    assert cli.main(["scenarios"]) == 0
    out, err = capsys.readouterr()
    assert "paper-case-1" in out
    assert err.startswith("jaxarm: warning: no compilation cache: compilation cache directory")
