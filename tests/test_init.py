"""The package's face: ``import mbn`` is free of work, and the README's library example runs with
names from ``mbn`` alone."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np

import mbn

README = Path(__file__).resolve().parents[1] / "README.md"


def test_import_mbn_imports_neither_jax_nor_matplotlib():
    code = "import sys, mbn; print('jax' in sys.modules, 'matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]


def test_every_name_of_the_surface_resolves():
    for name in mbn.__all__:
        assert getattr(mbn, name) is not None, name
    assert set(dir(mbn)) == set(mbn.__all__)


def test_the_readme_library_example_runs_with_names_from_mbn_alone():
    text = README.read_text()
    block = re.search(r"## Library in five lines\n\n```python\n(.*?)```", text, re.S)
    assert block is not None
    code = block.group(1)
    imports = [line for line in code.splitlines() if line.startswith(("from ", "import "))]
    assert all(line.startswith(("from mbn import", "import jax")) for line in imports), imports
    scope: dict = {}
    exec(compile(code, str(README), "exec"), scope)
    rates = np.asarray(scope["rates"])
    assert rates.shape == (4000, 3) and np.all(np.isfinite(rates))
    assert np.all((rates >= 0) & (rates <= 1))  # firing rates (the weights of hundreds saturate)
