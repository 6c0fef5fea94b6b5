"""The one figure helper and the one PNG writer every picture uses."""

from __future__ import annotations

import subprocess
import sys

import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from PIL import Image

from mbn.errors import MbnInputError
from mbn.viz.style import DPI, new_figure, save_png


def test_new_figure_has_its_own_agg_canvas_and_the_default_dpi():
    fig = new_figure((4.0, 3.0))
    assert isinstance(fig.canvas, FigureCanvasAgg)
    assert fig.dpi == DPI and fig.get_layout_engine() is not None
    assert new_figure((4.0, 3.0), dpi=80, layout=None).get_layout_engine() is None


def test_save_png_writes_the_figure_at_its_dpi_atomically(tmp_path):
    fig = new_figure((4.0, 3.0))
    fig.add_subplot().plot([0, 1], [0, 1])
    out = tmp_path / "f.png"
    save_png(fig, out)
    with Image.open(out) as im:
        assert im.format == "PNG" and im.size == (round(4 * DPI), round(3 * DPI))
    save_png(fig, out, dpi=50)
    with Image.open(out) as im:
        assert im.size == (200, 150)
    assert [p.name for p in tmp_path.iterdir()] == ["f.png"]  # no temporary file left behind
    with pytest.raises(MbnInputError, match="does not exist"):
        save_png(fig, tmp_path / "missing" / "f.png")


def test_save_png_tight_crops_to_what_is_drawn(tmp_path):
    fig = new_figure((6.0, 6.0), layout=None)
    fig.text(0.5, 0.5, "x")
    save_png(fig, tmp_path / "t.png", tight=True)
    with Image.open(tmp_path / "t.png") as im:
        assert im.width < 6 * DPI / 4 and im.height < 6 * DPI / 4


def test_pictures_leave_matplotlib_global_state_alone(tmp_path):
    code = (
        "import sys, mbn.viz, mbn.viz.multiplier;"
        " assert 'matplotlib' not in sys.modules, 'import mbn.viz imported matplotlib';"
        # rcParams._get reads the backend setting without resolving it
        " import matplotlib; backend = matplotlib.rcParams._get('backend');"
        " from mbn.viz import save_maze_png; from mbn.world.mazes import load_maze;"
        " save_maze_png(load_maze('cross_LS'), sys.argv[1]);"
        " assert 'matplotlib.pyplot' not in sys.modules, 'pyplot imported';"
        " assert matplotlib.rcParams._get('backend') == backend, 'backend changed'"
    )
    subprocess.run([sys.executable, "-c", code, str(tmp_path / "m.png")], check=True)
    assert (tmp_path / "m.png").stat().st_size > 1000
