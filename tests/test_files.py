"""Writing a file whole or not at all (femcrowd/files.py): a write that fails or comes out cut short leaves the
file there before byte for byte and no temporary file; no write follows a symbolic link."""

import errno
import os

import pytest

from femcrowd.errors import InputError
from femcrowd.files import TEMPORARY, complete, make_directory, replaced, write_text

PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"


def leftovers(directory):
    return sorted(p.name for p in directory.glob(TEMPORARY))


def test_a_full_disk_leaves_the_previous_file(tmp_path):
    """The writer's own error (ENOSPC after half a file): one line naming the file, the old file kept."""
    path = tmp_path / "summary.json"
    write_text(path, '{"old": 1}\n')
    with pytest.raises(InputError) as err:
        with replaced(path) as tmp:
            tmp.write_bytes(b'{"new": ')
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    assert str(err.value) == f"{path}: cannot write: No space left on device"
    assert path.read_bytes() == b'{"old": 1}\n' and leftovers(tmp_path) == []


@pytest.mark.parametrize("name, whole, cut", [
    ("mesh.msh", b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Elements\n1\n1 2 2 1 1 1 2 3\n$EndElements\n",
     b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Elements\n1\n1 2 2 1 1 1 2"),
    ("frame.vtu", b'<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid">\n</VTKFile>\n',
     b'<?xml version="1.0"?>\n<VTKFile type="Unstr'),
    ("picture.png", b"\x89PNG\r\n\x1a\n" + b"\x00" * 40 + PNG_END, b"\x89PNG\r\n\x1a\n" + b"\x00" * 40),
    ("movie.gif", b"GIF89a" + b"\x00" * 20 + b";", b"GIF89a" + b"\x00" * 20),
    ("table.csv", b"a,b\n1,2\n", b""),
])
def test_a_file_cut_short_without_an_error_is_not_renamed(tmp_path, name, whole, cut):
    """A writer that reports nothing on a full disk (gmsh, VTK): the file's closing bytes are checked (an empty
    file for the formats without them); the old file kept, the whole one accepted."""
    path = tmp_path / name
    with replaced(path) as tmp:
        tmp.write_bytes(whole)
    assert path.read_bytes() == whole and complete(path)
    with pytest.raises(InputError, match="cannot write: the file came out incomplete"):
        with replaced(path) as tmp:
            tmp.write_bytes(cut)
    assert path.read_bytes() == whole and leftovers(tmp_path) == []


def test_the_temporary_file_keeps_the_format_suffix(tmp_path):
    """Writers choose the format by the suffix (gmsh, matplotlib, PIL, imageio): the temporary file has it."""
    with replaced(tmp_path / "curves.png") as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".png" and tmp.match(TEMPORARY)
        tmp.write_bytes(b"\x89PNG" + PNG_END)


def test_no_write_through_a_link_at_the_name(tmp_path):
    target, link = tmp_path / "target.txt", tmp_path / "history.csv"
    target.write_text("not femcrowd's\n")
    link.symlink_to(target)
    with pytest.raises(InputError, match="symbolic link"):
        write_text(link, "time\n0\n")
    assert target.read_text() == "not femcrowd's\n" and link.is_symlink() and leftovers(tmp_path) == []


def test_a_directory_femcrowd_names_may_not_be_a_link(tmp_path):
    """plots/ as a link elsewhere is refused (nothing made there); a directory the user names (-o) may be one."""
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (tmp_path / "plots").symlink_to(elsewhere)
    with pytest.raises(InputError, match="plots: cannot write: it is a symbolic link"):
        make_directory(tmp_path / "plots", own=True)
    assert make_directory(tmp_path / "plots") == tmp_path / "plots"
    assert list(elsewhere.iterdir()) == []
