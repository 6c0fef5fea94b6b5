"""The world commands: mbn mazes, sonar, drive, show-maze — outputs and bad-input handling."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from mbn.cli.main import main
from mbn.world.mazes.builtin import BUILTIN_NAMES

DATA = Path(__file__).parent.parent / "data" / "stage"


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_mazes_lists_every_builtin(capsys):
    assert main(["mazes", "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)
    assert list(listed) == list(BUILTIN_NAMES)
    assert main(["mazes"]) == 0
    out = capsys.readouterr().out
    assert all(name in out for name in BUILTIN_NAMES)


@pytest.mark.slow  # the library's checks run in CI (tests/world)
def test_sonar_reproduces_stage_readings(tmp_path):
    stage = _rows(DATA / "sonar_res0.005.csv")[:60]
    poses = tmp_path / "poses.csv"
    poses.write_text("x,y,theta\n" + "".join(f"{r['x']},{r['y']},{r['theta']}\n" for r in stage))
    out = tmp_path / "ranges.csv"
    assert main(["sonar", "--maze", "stage_arena", "--poses", str(poses), "--out", str(out)]) == 0
    rows = _rows(out)
    assert list(rows[0]) == ["x", "y", "theta"] + [f"s{i:02d}" for i in range(16)]
    ours = np.array([[float(r[f"s{i:02d}"]) for i in range(16)] for r in rows])
    ref = np.array([[float(r[f"s{i:02d}"]) for i in range(16)] for r in stage])
    assert np.median(np.abs(ours - ref)) < 0.005
    assert ours.max() <= 5.0


def test_drive_reproduces_stage_kinematics(tmp_path):
    out = tmp_path / "drive.csv"
    args = ["drive", "--start", "0,0,0", "--cmd", "0.3,0.5", "--seconds", "5", "--out", str(out)]
    assert main(args) == 0
    rows = _rows(out)
    assert list(rows[0]) == ["step", "t", "x", "y", "theta", "v", "w", "stall"]
    assert len(rows) == 51 and rows[0]["step"] == "0" and rows[-1]["step"] == "50"
    last = rows[-1]
    # Stage: (0.3, 0.5) from the origin ends at (0.38603, 1.07148, 2.5) with 100 ms steps
    assert float(last["x"]) == pytest.approx(0.38603, abs=1e-5)
    assert float(last["y"]) == pytest.approx(1.07148, abs=1e-5)
    assert float(last["theta"]) == pytest.approx(2.5, abs=1e-9)
    # the clipped command is reported as applied
    clipped = tmp_path / "clip.csv"
    args = ["drive", "--start", "0,0,0", "--cmd", "0.8,2", "--seconds", "0.5", "--dt", "0.1"]
    assert main([*args, "--out", str(clipped)]) == 0
    r1 = _rows(clipped)[1]
    assert float(r1["v"]) == 0.5 and float(r1["w"]) == pytest.approx(np.pi / 2)


@pytest.mark.slow  # the library's checks run in CI (tests/world)
def test_drive_into_a_wall_stalls(tmp_path):
    out = tmp_path / "d.csv"
    args = ["drive", "--maze", "cross_S", "--start", "4.2,0.6,1.5707963", "--cmd", "0.5,0"]
    assert main([*args, "--seconds", "20", "--out", str(out)]) == 0
    rows = _rows(out)
    stall = np.array([int(r["stall"]) for r in rows])
    y = np.array([float(r["y"]) for r in rows])
    assert stall.sum() > 0 and np.all(stall[np.argmax(stall) :] == 1)
    assert y.max() + 0.21085 <= 8.4  # the front never passes the end wall


@pytest.mark.slow  # the library's checks run in CI (tests/world)
def test_drive_in_chunks_equals_one_run(tmp_path, monkeypatch):
    args = ["drive", "--maze", "fig4", "--start", "4.2,11.4,0", "--cmd", "0.5,0.3"]
    one, chunked = tmp_path / "one.csv", tmp_path / "chunked.csv"
    assert main([*args, "--seconds", "60", "--out", str(one)]) == 0  # one chunk of 600 moves
    monkeypatch.setattr("mbn.cli.world._DRIVE_CHUNK", 77)
    assert main([*args, "--seconds", "60", "--out", str(chunked)]) == 0
    assert one.read_text() == chunked.read_text()
    assert sum(int(r["stall"]) for r in _rows(one)) > 0


# the TOML example of docs/mazes.md (its edges on a 0.1 m step: the segment path)
DOCS_TOML = """\
[[free]]
xmin = 0.0
xmax = 6.0
ymin = 0.0
ymax = 1.2
[[wall]]
xmin = 2.0
xmax = 2.4
ymin = 0.0
ymax = 0.3
[[tile]]
x = 4.0
y = 0.6
colors = 2
heading = 0
[[start]]
x = 0.6
y = 0.6
theta = 0
"""


@pytest.mark.slow  # the library's checks run in CI (tests/world)
def test_sonar_and_drive_in_a_world_that_is_not_a_grid(tmp_path):
    from mbn.world.geometry import collides, rect_segments, sonar_ranges
    from mbn.world.mazes.load import load_maze

    maze_file = tmp_path / "corridor.toml"
    maze_file.write_text(DOCS_TOML.replace("2.4", "2.43").replace("0.3", "0.31"))
    rng = np.random.default_rng(0)
    poses = np.stack(
        [rng.uniform(0.5, 1.6, 50), rng.uniform(0.45, 0.75, 50), rng.uniform(-3, 3, 50)], -1
    )
    pfile = tmp_path / "poses.csv"
    pfile.write_text("x,y,theta\n" + "".join(f"{x!r},{y!r},{t!r}\n" for x, y, t in poses.tolist()))
    out = tmp_path / "ranges.csv"
    assert main(["sonar", "--maze", str(maze_file), "--poses", str(pfile), "--out", str(out)]) == 0
    ours = np.array([[float(r[f"s{i:02d}"]) for i in range(16)] for r in _rows(out)])
    maze = load_maze(str(maze_file))
    exact = np.asarray(sonar_ranges(poses, rect_segments(maze.solid_rects())))
    np.testing.assert_allclose(ours, exact, rtol=0, atol=2e-5)
    drive = tmp_path / "drive.csv"
    args = ["drive", "--maze", str(maze_file), "--start", "0.6,0.45,0", "--cmd", "0.5,0"]
    assert main([*args, "--seconds", "10", "--out", str(drive)]) == 0
    rows = _rows(drive)
    pose = np.array([[float(r[k]) for k in ("x", "y", "theta")] for r in rows])
    assert int(rows[-1]["stall"]) == 1 and pose[:, 0].max() > 1.7  # stopped by the wall at 2 m
    assert not np.asarray(collides(pose, maze.solid_rects())).any()


@pytest.mark.parametrize(
    "args,message",
    [
        (["sonar", "--maze", "nowhere", "--poses", "P", "--out", "O"], "cross_LSR"),
        (["drive", "--start", "0,0", "--cmd", "1,1", "--seconds", "1", "--out", "O"], "--start"),
        (
            ["drive", "--start", "0,0,0", "--cmd", "1,1", "--seconds", "0.15", "--out", "O"],
            "whole number",
        ),
        (
            [
                "drive",
                "--maze",
                "cross_S",
                "--start",
                "0.5,0.5,0",
                "--cmd",
                "1,1",
                "--seconds",
                "1",
                "--out",
                "O",
            ],
            "overlaps a wall",
        ),
    ],
)
def test_bad_arguments_exit_2_with_one_line(args, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("P").write_text("x,y,theta\n4.2,0.6,0\n")
    assert _exit_code(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err
    assert not Path("O").exists()


def _exit_code(args: list[str]) -> int:
    """main's return value, or the status of the SystemExit argparse raises."""
    try:
        return main(args)
    except SystemExit as exc:
        return int(exc.code or 0)


def test_sonar_input_errors_name_file_and_line(tmp_path, capsys):
    poses = tmp_path / "p.csv"
    poses.write_text("x,y\n1,2\n")
    out = tmp_path / "o.csv"
    assert main(["sonar", "--maze", "cross_S", "--poses", str(poses), "--out", str(out)]) == 2
    assert f"{poses}:1: missing column(s) theta" in capsys.readouterr().err
    poses.write_text("x,y,theta\n4.2,0.6,0\n0.3,0.3,0\n")
    assert main(["sonar", "--maze", "cross_S", "--poses", str(poses), "--out", str(out)]) == 2
    assert f"{poses}:3: pose" in capsys.readouterr().err
    bad = tmp_path / "bad.maze"
    bad.write_text("; a maze\n#####\n#.x.#\n#####\n")
    assert main(["sonar", "--maze", str(bad), "--poses", str(poses), "--out", str(out)]) == 2
    assert f"{bad}:3: unknown character 'x'" in capsys.readouterr().err
    assert not out.exists()


def test_show_maze_writes_a_png(tmp_path, capsys):
    from PIL import Image

    out = tmp_path / "fig4.png"
    assert main(["show-maze", "fig4", "--out", str(out)]) == 0
    with Image.open(out) as im:
        assert im.format == "PNG" and im.size[0] > 400 and im.size[1] > 300
    bad = tmp_path / "bad.toml"
    bad.write_text("name = 'x'\n[[wall]]\nxmin = 0\nxmax = oops\n")
    assert main(["show-maze", str(bad), "--out", str(tmp_path / "b.png")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"{bad}:4" in err
    assert not (tmp_path / "b.png").exists()
