"""Every command shown in README.md and docs/*.md, run exactly as written from the root of a copy of the
repository, document by document and in the order shown (later commands may use what earlier ones wrote).

Commands are the lines of the ```bash blocks (a trailing backslash continues a line); a ```python block
runs as one program, and a ```python block after a line `<!-- continued -->` continues the one before it (the
cells of a notebook: the two run as one program, where the later stands). A block after a line `<!-- slow -->`
runs only in the slow tier (`pytest -m slow`): the long studies and the install commands. ```text blocks (usage
synopses, printed output) are not run.
"""

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from .support import ROOT

DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
#: what a copy of the repository leaves out: what is not part of a checkout, and what runs write
IGNORE = shutil.ignore_patterns(".git", ".venv", "__pycache__", "*.egg-info", ".pytest_cache", ".cache", "output",
                                "stress-output", "results")


def command_blocks(path):
    """[(line number of the fence, [commands], slow)] of the ```bash and ```python blocks of a markdown file."""
    blocks, lines = [], path.read_text().splitlines()
    k, cell = 0, (None, [])   # the last python block: its fence's line, its program
    while k < len(lines):
        if lines[k].strip() in ("```bash", "```python"):
            slow = k > 0 and lines[k - 1].strip() == "<!-- slow -->"
            start, body, python = k + 1, [], lines[k].strip() == "```python"
            k += 1
            while lines[k].strip() != "```":
                body.append(lines[k])
                k += 1
            if python and lines[start - 2].strip() == "<!-- continued -->" and blocks and blocks[-1][0] == cell[0]:
                blocks.pop()   # the program so far runs here, with this cell
                body = cell[1] + body
            if python:
                cell = (start, body)
                commands = [f"python -c {shlex.quote(chr(10).join(body))}"]
            else:
                text = re.sub(r"\\\n\s*", " ", "\n".join(body))
                commands = [c for c in text.splitlines() if c.strip() and not c.lstrip().startswith("#")]
            blocks.append((start, commands, slow))
        k += 1
    return blocks


def run_document(path, tmp_path, slow):
    """Run the blocks of one document in a fresh copy of the repository (the slow ones too when slow)."""
    copy = tmp_path / "femcrowd"
    shutil.copytree(ROOT, copy, ignore=IGNORE, symlinks=True)
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    ran = 0
    for line, commands, is_slow in command_blocks(path):
        if is_slow and not slow:
            continue
        for command in commands:
            done = subprocess.run(["bash", "-c", command], cwd=copy, env=env, capture_output=True, text=True,
                                  timeout=3600)
            assert done.returncode == 0, (f"{path.name}:{line}: `{command}` exited with {done.returncode}\n"
                                          f"{done.stdout[-2000:]}\n{done.stderr[-2000:]}")
            ran += 1
    return ran


def has_commands(path, slow):
    return any(is_slow == slow for _, _, is_slow in command_blocks(path))


@pytest.mark.parametrize("path", [p for p in DOCUMENTS if has_commands(p, slow=False)],
                         ids=lambda p: p.relative_to(ROOT).as_posix())
def test_commands_run_as_written(path, tmp_path):
    assert run_document(path, tmp_path, slow=False) > 0


@pytest.mark.slow
@pytest.mark.parametrize("path", [p for p in DOCUMENTS if has_commands(p, slow=True)],
                         ids=lambda p: p.relative_to(ROOT).as_posix())
def test_all_commands_run_as_written(path, tmp_path):
    """The slow tier: every block, the long studies and the install commands included."""
    assert run_document(path, tmp_path, slow=True) > 0


def test_the_parser_finds_blocks_and_their_tier(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("text\n```bash\nfemcrowd run a \\\n  --set b=1  # comment\n# not a command\n```\n"
                    "<!-- slow -->\n```bash\nfemcrowd stress\n```\n```text\nfemcrowd run CASE\n```\n"
                    "```python\nimport femcrowd\nprint(1)\n```\n")
    assert command_blocks(page) == [(2, ["femcrowd run a  --set b=1  # comment"], False),
                                    (8, ["femcrowd stress"], True),
                                    (14, ["python -c 'import femcrowd\nprint(1)'"], False)]


def test_a_continued_python_block_runs_with_the_one_before(tmp_path):
    """Notebook cells: the second block runs the first's code and its own, as one program; the first alone is not
    run; a block after a bash block does not continue across it."""
    page = tmp_path / "page.md"
    page.write_text("```python\nx = 1\n```\n<!-- continued -->\n```python\nprint(x)\n```\n"
                    "```bash\nls\n```\n<!-- continued -->\n```python\ny = 2\n```\n")
    assert command_blocks(page) == [(5, ["python -c 'x = 1\nprint(x)'"], False), (8, ["ls"], False),
                                    (12, ["python -c 'y = 2'"], False)]
