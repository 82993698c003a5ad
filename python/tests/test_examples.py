"""The README's Python example is python/examples/quickstart.py, and it runs."""

import re
import subprocess
import sys

from conftest import REPO

QUICKSTART = REPO / "python/examples/quickstart.py"


def code_of(text):
    """The code after a module docstring."""
    return re.sub(r'^""".*?"""\s*', "", text, flags=re.S).strip()


def test_the_readme_example_is_the_quickstart():
    readme = (REPO / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", readme, flags=re.S)
    assert blocks, "README has no Python example"
    assert blocks[0].strip() == code_of(QUICKSTART.read_text())
    assert len(blocks[0].strip().splitlines()) <= 15


def test_the_quickstart_runs_and_finds_the_press():
    out = subprocess.run([sys.executable, str(QUICKSTART)], cwd=REPO, check=True,
                         capture_output=True, text=True).stdout.splitlines()
    assert len(out) == 7
    contacts = [int(re.search(r"(\d+) contact points", line).group(1)) for line in out]
    assert contacts[0] == 0 and max(contacts) > 0
