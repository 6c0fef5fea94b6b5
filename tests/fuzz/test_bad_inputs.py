"""The bad-input suite: every reader and every command fed a corpus of bad inputs generated here,
and random bytes (hypothesis) fed to every parser. Each case must give exit status 2, one line on
stderr starting ``mbn: error:``, no traceback, and write nothing (``docs/bad-input.md``)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mbn.cli.main import main
from mbn.errors import MbnInputError

# -------------------------------------------------------------------------------------------
# The corpus: (class, name, file contents) for each reader
# -------------------------------------------------------------------------------------------

_NOT_UTF8 = b"\xff\xfe\x00bad"

JSON_BAD: list[tuple[str, bytes]] = [
    ("empty", b""),
    ("not utf-8", _NOT_UTF8),
    ("not json", b"{kind: ctrnn"),
    ("truncated", b'{"kind": "mbn.controller.ctrnn", "network": {"W": [[1'),
    ("a list", b"[1, 2, 3]"),
    ("a number", b"42"),
    ("nested 100000 deep", b"[" * 100_000 + b"]" * 100_000),
    ("integer of 5000 digits", b'{"a": ' + b"9" * 5000 + b"}"),
    ("NaN literal", b'{"kind": NaN}'),
    ("unknown kind", b'{"kind": "mbn.controller.brain", "format_version": 1}'),
]


def _controller_variants() -> list[tuple[str, bytes]]:
    """A valid controller file, then broken one field at a time."""
    from mbn.controllers import CTRNNControllerSpec, controller_to_dict
    from mbn.paper import published_rf

    good = controller_to_dict(CTRNNControllerSpec(net=published_rf(), behavior="right"))

    def broken(change: Callable[[dict], None]) -> bytes:
        data = json.loads(json.dumps(good))
        change(data)
        return json.dumps(data).encode()

    def setter(*path: str, value: object) -> Callable[[dict], None]:
        def change(d: dict) -> None:
            for p in path[:-1]:
                d = d[p]
            d[path[-1]] = value

        return change

    return [
        ("weights as text", broken(setter("network", "W", value=[["1"] * 3] * 3))),
        ("weight too large for float32", broken(setter("network", "tau", value=[1e39] * 3))),
        ("tau of 0", broken(setter("network", "tau", value=[0.0] * 3))),
        ("substeps 10^9", broken(setter("substeps", value=10**9))),
        ("dt of a million seconds", broken(setter("dt", value=1e6))),
        ("dt as text", broken(setter("dt", value="0.1"))),
        ("an unknown field", broken(setter("extra", value=1))),
        ("format version 99", broken(setter("format_version", value=99))),
        ("motor neuron 9", broken(setter("motor", "speed_neuron", value=9))),
        ("sonars as text", broken(setter("sensors", "sonars", value="all"))),
    ]


CSV_BAD: list[tuple[str, bytes]] = [
    ("empty", b""),
    ("not utf-8", b"x1,x2\n0.5," + _NOT_UTF8 + b"\n"),
    ("missing column", b"x1\n0.5\n"),
    ("a word", b"x1,x2\n0.5,half\n"),
    ("infinite", b"x1,x2\n0.5,inf\n"),
    ("short row", b"x1,x2\n0.5\n"),
    ("a field of 200000 characters", b"x1,x2\n" + b"1" * 200_000 + b",1\n"),
]

MAZE_BAD: list[tuple[str, str, bytes]] = [
    (".maze", "not utf-8", _NOT_UTF8),
    (".maze", "a bad character", b"###\n#@#\n###\n"),
    (".maze", "no free space", b"###\n###\n"),
    (".toml", "not toml", b"[[wall]\nxmin = 0\n"),
    (
        ".toml",
        "integer of 400 digits",
        b"[[wall]]\nxmin = " + b"9" * 400 + b"\nxmax=1\nymin=0\nymax=1\n",
    ),
    (".toml", "a wall with xmin > xmax", b"[[wall]]\nxmin = 2\nxmax = 1\nymin = 0\nymax = 1\n"),
    (".world", "nested 5000 deep", b"define m model ( )\n" + b"m (\n" * 5000 + b")\n" * 5000),
    (".world", "unclosed", b'floorplan ( name "x"\n'),
    (".world", "a missing bitmap", b'floorplan ( bitmap "nowhere.png" size [1 1 1] )\n'),
]

SETTINGS_BAD: list[tuple[str, bytes]] = [
    ("not utf-8", _NOT_UTF8),
    ("not toml", b"[rf\n"),
    ("unknown section", b"[rff]\ngenerations = 1\n"),
    ("unknown key", b"[rf]\nspeed = 1\n"),
    ("out of range", b"[de]\nF = 3.0\n"),
    ("wrong type", b"[rf]\ngenerations = 'many'\n"),
    ("integer of 400 digits", b"[rf]\ngenerations = " + b"9" * 400 + b"\n"),
    ("integer of 5000 digits", b"[rf]\ngenerations = " + b"9" * 5000 + b"\n"),
    ("absurd budget", b"[rf]\ngenerations = 1000000000\n"),
]

RUN_JSON_BAD: list[tuple[str, bytes]] = [
    ("a list", b"[1]"),
    ("not utf-8", _NOT_UTF8),
    ("another kind", b'{"kind": "mbn.sweep", "seed": 0}'),
    ("truncated", b'{"kind": "mbn.reproduce", "se'),
]


def _check(capsys, tmp_path: Path, argv: list[str], outputs: list[Path]) -> None:
    status = main([str(a) for a in argv])
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert status == 2, (argv, captured.out, err)
    assert len(err.splitlines()) == 1, err
    assert err.startswith("mbn: error: ") and "Traceback" not in err, err
    assert len(err) < 400, err
    for out in outputs:
        assert not out.exists(), out
    assert not list(tmp_path.rglob(".*.tmp"))


def _write(tmp_path: Path, name: str, data: bytes) -> Path:
    path = tmp_path / name
    path.write_bytes(data)
    return path


# -------------------------------------------------------------------------------------------
# Every reader, through the commands that read it
# -------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("case", "data"), JSON_BAD + _controller_variants())
def test_bad_controller_files(tmp_path, capsys, case, data):
    path = _write(tmp_path, "c.json", data)
    _check(
        capsys,
        tmp_path,
        ["evaluate", "--controller", path, "--maze", "fig4", "--behavior", "right"],
        [],
    )


@pytest.mark.parametrize(("case", "data"), JSON_BAD)
def test_bad_multiplier_files(tmp_path, capsys, case, data):
    path = _write(tmp_path, "m.json", data)
    pairs = _write(tmp_path, "p.csv", b"x1,x2\n0.5,0.5\n")
    out = tmp_path / "o.csv"
    _check(
        capsys, tmp_path, ["mul", "eval", "--pairs", pairs, "--params", path, "--out", out], [out]
    )
    png = tmp_path / "r.png"
    _check(capsys, tmp_path, ["mul", "report", "--params", path, "--out", png], [png])
    _check(capsys, tmp_path, ["pnn", "check", "--params", path, "--sequences", "2"], [])


@pytest.mark.parametrize(("case", "data"), CSV_BAD)
def test_bad_pairs_files(tmp_path, capsys, case, data):
    path = _write(tmp_path, "p.csv", data)
    out = tmp_path / "o.csv"
    _check(capsys, tmp_path, ["mul", "eval", "--pairs", path, "--out", out], [out])


@pytest.mark.parametrize(("case", "data"), CSV_BAD)
def test_bad_poses_files(tmp_path, capsys, case, data):
    path = _write(tmp_path, "p.csv", data.replace(b"x1,x2", b"x,y,theta"))
    out = tmp_path / "o.csv"
    _check(
        capsys, tmp_path, ["sonar", "--maze", "stage_arena", "--poses", path, "--out", out], [out]
    )


@pytest.mark.parametrize(("suffix", "case", "data"), MAZE_BAD)
@pytest.mark.parametrize("command", ["show-maze", "sonar", "evaluate"])
def test_bad_maze_files(tmp_path, capsys, suffix, case, data, command):
    path = _write(tmp_path, f"m{suffix}", data)
    out = tmp_path / "o.png"
    if command == "show-maze":
        argv = ["show-maze", path, "--out", out]
    elif command == "sonar":
        poses = _write(tmp_path, "p.csv", b"x,y,theta\n0.5,0.5,0\n")
        argv = ["sonar", "--maze", path, "--poses", poses, "--out", out]
    else:
        from mbn.controllers import CTRNNControllerSpec, save_controller
        from mbn.paper import published_rf

        ctl = tmp_path / "rf.json"
        save_controller(ctl, CTRNNControllerSpec(net=published_rf(), behavior="right"))
        argv = ["evaluate", "--controller", ctl, "--maze", path, "--behavior", "right"]
    _check(capsys, tmp_path, argv, [out])


@pytest.mark.parametrize(("case", "data"), SETTINGS_BAD)
def test_bad_settings_files(tmp_path, capsys, case, data):
    path = _write(tmp_path, "s.toml", data)
    out = tmp_path / "run"
    _check(capsys, tmp_path, ["reproduce", "--config", path, "--out", out], [out])


@pytest.mark.parametrize(("case", "data"), RUN_JSON_BAD)
def test_bad_run_manifests(tmp_path, capsys, case, data):
    run = tmp_path / "run"
    run.mkdir()
    (run / "run.json").write_bytes(data)
    _check(
        capsys, tmp_path, ["reproduce", "--quick", "--out", run, "--resume"], [run / "results.json"]
    )


# -------------------------------------------------------------------------------------------
# Random bytes into every parser: a clear MbnInputError or a result, never anything else
# -------------------------------------------------------------------------------------------


def _parsers(tmp_path: Path) -> dict[str, Callable[[Path], object]]:
    from mbn.config import read_toml
    from mbn.controllers import read_controller_spec
    from mbn.experiments.reproduce import REPRODUCE
    from mbn.io import read_csv_columns
    from mbn.networks.multiplier import load_multiplier
    from mbn.world.mazes.load import load_maze

    return {
        "controller": read_controller_spec,
        "multiplier": load_multiplier,
        "csv": lambda p: read_csv_columns(p, ["x1", "x2"]),
        "settings": lambda p: REPRODUCE.config(document=read_toml(p)),
        ".maze": lambda p: load_maze(p.rename(p.with_suffix(".maze"))),
        ".toml": lambda p: load_maze(p.rename(p.with_suffix(".toml"))),
        ".world": lambda p: load_maze(p.rename(p.with_suffix(".world"))),
    }


_TOKENS = st.sampled_from(
    [
        b"{",
        b"}",
        b"[",
        b"]",
        b'"kind"',
        b":",
        b",",
        b"1e999",
        b"-0",
        b"9" * 30,
        b"\n",
        b"[[wall]]\n",
        b"xmin = ",
        b"#",
        b".",
        b">",
        b"cell = ",
        b"model (",
        b")",
        b'"x"',
        b"\xff",
        b"nan",
        b"true",
        b"=",
        b"[rf]\n",
        b"generations = ",
    ]
)


@pytest.mark.parametrize(
    "reader", ["controller", "multiplier", "csv", "settings", ".maze", ".toml", ".world"]
)
@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.one_of(st.binary(max_size=200), st.lists(_TOKENS, max_size=40).map(b"".join)))
def test_random_bytes_give_a_clear_error_or_a_result(tmp_path, reader, data):
    path = tmp_path / "input"
    path.write_bytes(data)
    try:
        _parsers(tmp_path)[reader](path)
    except MbnInputError as exc:
        message = str(exc)
        assert message and "\n" not in message and len(message) < 400, message
    finally:
        for p in tmp_path.iterdir():
            p.unlink()
