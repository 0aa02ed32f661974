"""Output files (``jaxarm.io.files``): checked before any work, written whole or not at all."""

import pathlib

import pytest

from jaxarm.io.files import output_file, output_folder, written


def test_written_replaces_the_file_only_when_the_block_ends_normally(tmp_path):
    target = tmp_path / "r.json"
    target.write_text("old")
    with pytest.raises(KeyboardInterrupt):
        with written(target) as path:
            assert path.parent == tmp_path and path.suffix == ".json" and path != target
            path.write_text("half")
            raise KeyboardInterrupt
    assert [p.name for p in tmp_path.iterdir()] == ["r.json"] and target.read_text() == "old"
    with written(target) as path:
        path.write_text("new")
    assert [p.name for p in tmp_path.iterdir()] == ["r.json"] and target.read_text() == "new"


def test_outputs_that_cannot_be_written_name_the_flag(tmp_path):
    (tmp_path / "file").write_text("")
    with pytest.raises(ValueError, match=r"--json '.*missing/r.json': folder .* does not exist"):
        output_file("--json", tmp_path / "missing" / "r.json")
    with pytest.raises(ValueError, match=r"--csv '.*' is a folder; give a file name"):
        output_file("--csv", tmp_path)
    with pytest.raises(ValueError, match=r"--out '.*file' is a file, not a folder"):
        output_folder("--out", tmp_path / "file")
    with pytest.raises(ValueError, match=r"--out '.*file/a/b': '.*file' is a file, not a folder"):
        output_folder("--out", tmp_path / "file" / "a" / "b")
    assert output_folder("--out", tmp_path / "new" / "folder") == tmp_path / "new" / "folder"
    assert not (tmp_path / "new").exists()  # checked, not created


@pytest.mark.skipif(not pathlib.Path("/proc/self").is_dir(), reason="no /proc")
def test_a_folder_where_no_file_can_be_made_is_named_before_any_work(tmp_path):
    # /proc: a folder whose permissions say writable (to root) where no file can be created
    with pytest.raises(ValueError, match=r"--csv '/proc/x.csv': cannot create a file in folder "
                                         r"'/proc': "):
        output_file("--csv", "/proc/x.csv")
    assert output_file("--csv", tmp_path / "x.csv") == tmp_path / "x.csv"
    assert list(tmp_path.iterdir()) == []  # the probe is gone


def test_a_writer_that_fails_on_the_temporary_file_names_the_path_asked_for(tmp_path):
    target = tmp_path / "r.csv"
    with pytest.raises(FileNotFoundError) as raised:
        with written(target) as path:
            with written(path) as inner:  # a writer that writes through ``written`` too
                raise FileNotFoundError(2, "No such file or directory", str(inner))
    assert raised.value.filename == str(target)
    assert list(tmp_path.iterdir()) == []


def test_written_keeps_links_and_writes_devices_in_place(tmp_path):
    (tmp_path / "real.csv").write_text("old")
    (tmp_path / "link.csv").symlink_to(tmp_path / "real.csv")
    with written(tmp_path / "link.csv") as path:
        path.write_text("new")
    assert (tmp_path / "link.csv").is_symlink() and (tmp_path / "real.csv").read_text() == "new"
    with written("/dev/null") as path:
        assert str(path) == "/dev/null"
        path.write_text("discarded")
    assert output_file("--json", "/dev/null") == pathlib.Path("/dev/null")
