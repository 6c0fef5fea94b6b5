"""The robot-world commands of ``mbn``: ``mazes``, ``show-maze``, ``sonar`` and ``drive``."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from mbn.cli.args import number_in, numbers
from mbn.errors import MbnInputError
from mbn.io import json_text
from mbn.precision import NETWORKS

__all__ = ["EPILOG", "add_commands"]

EPILOG = """\
  mbn mazes                                   the built-in mazes
  mbn mazes generate grid --seed 7 --out g.maze   a generated maze (also named grid:7)
  mbn show-maze fig4 --out fig4.png           draw a maze: walls, tiles, junctions, starts
  mbn sonar --maze stage_arena --poses poses.csv --out ranges.csv
  mbn drive --start 0,0,0 --cmd 0.3,0.5 --seconds 5 --out drive.csv
"""


#: The largest ``.maze`` grid ``mbn show-maze`` reads (cells): a picture of a few thousand pixels
#: shows no more, and a 1000 x 1000 grid draws in seconds (its walls and decision cells as raster
#: images: :data:`mbn.viz.maze.MAX_PATCHES`).
MAX_DRAW_CELLS = 1_000_000

#: Moves per jitted chunk of ``mbn drive`` (the trajectory of one chunk is held in memory).
_DRIVE_CHUNK = 20_000


def _triple(text: str) -> tuple[float, float, float]:
    return numbers(text, 3)  # type: ignore[return-value]


def _pair(text: str) -> tuple[float, float]:
    return numbers(text, 2)  # type: ignore[return-value]


def add_commands(sub: Any, parser_class: type[argparse.ArgumentParser]) -> None:
    """Add the world commands to the ``mbn`` sub-parsers (geometry in float64:
    :mod:`mbn.precision`)."""
    raw = argparse.RawDescriptionHelpFormatter
    mazes = sub.add_parser(
        "mazes",
        help="list the built-in mazes",
        description="List the built-in mazes (names usable wherever a maze is asked for).",
        epilog="examples:\n"
        "  mbn mazes           one line per maze: its name and what it is\n"
        "  mbn mazes --json    the same as one JSON object",
        formatter_class=raw,
    )
    mazes.add_argument("--json", action="store_true", help="print one JSON object")
    mazes_sub = mazes.add_subparsers(dest="mazes_action", metavar="{generate,families}")
    generate = mazes_sub.add_parser(
        "generate",
        help="write a generated maze of a family as a .maze file",
        description="Write the maze a family's generator makes for a seed (docs/generalization.md)."
        " The same family, parameters and seed give the same maze; a seed belongs to one split "
        "(train, validation, test: `mbn mazes families`). A generated maze is also named "
        "FAMILY:SEED wherever a maze is asked for.",
        epilog="examples:\n"
        "  mbn mazes generate tiles2 --seed 2000000 --out t.maze   the first test maze\n"
        "  mbn mazes generate grid --seed 7 --set size=25,31 --out big.maze     a larger one",
        formatter_class=raw,
    )
    generate.add_argument("family", help="grid, tiles2 or tiles3")
    generate.add_argument("--seed", type=int, required=True, help="generator seed")
    generate.add_argument("--out", type=Path, required=True, help="output .maze file")
    generate.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="change a generator parameter (repeatable; a pair or list as 2,6)",
    )
    families = mazes_sub.add_parser(
        "families",
        help="the maze families, their parameters and splits",
        description="The maze families, their parameters, the generator seeds of the splits, "
        "and the zero-shot suite (docs/generalization.md).",
        epilog="examples:\n"
        "  mbn mazes families          each family's parameters, the splits, the zero-shot suite\n"
        "  mbn mazes families --json   the same as one JSON object",
        formatter_class=raw,
    )
    families.add_argument("--json", action="store_true", help="print one JSON object")
    generate.set_defaults(func=_cmd_mazes_generate, precision=NETWORKS, writes="file")
    families.set_defaults(func=_cmd_mazes_families, precision=NETWORKS)

    show = sub.add_parser(
        "show-maze",
        help="draw a maze as a PNG",
        description="Draw a maze: walls, tiles (one-, two- and three-colour), decision cells of "
        "grid mazes, and start poses.",
        epilog="maze: a built-in name (see `mbn mazes`) or a .maze, .toml or Player/Stage .world "
        f"file; a .maze grid of at most {MAX_DRAW_CELLS:,} cells (1000 x 1000)\n"
        "example:\n  mbn show-maze fig4 --out fig4.png",
        formatter_class=raw,
    )
    show.add_argument("maze", help="built-in name or maze file")
    show.add_argument("--out", type=Path, required=True, help="output PNG")

    sonar = sub.add_parser(
        "sonar",
        help="sonar readings at given poses",
        description="Read the 16 sonars of the Pioneer 3DX at each pose of a CSV (columns "
        "x,y,theta: metres, radians) and write x,y,theta,s00..s15 (metres, Stage's transducer "
        "order; a miss reads 5.0).",
        epilog="example:\n  mbn sonar --maze stage_arena --poses poses.csv --out ranges.csv",
        formatter_class=raw,
    )
    sonar.add_argument("--maze", required=True, help="built-in name or maze file")
    sonar.add_argument("--poses", type=Path, required=True, help="input CSV: x,y,theta")
    sonar.add_argument("--out", type=Path, required=True, help="output CSV")

    drive = sub.add_parser(
        "drive",
        help="drive with a constant command",
        description="Drive the robot with a constant command (v m/s, w rad/s) and write the "
        "pose after every step: step,t,x,y,theta,v,w,stall (v, w as applied after the P3DX "
        "limits; a colliding move is undone and marked stall = 1). Without --maze the world is "
        "empty.",
        epilog="example:\n  mbn drive --start 0,0,0 --cmd 0.3,0.5 --dt 0.1 --seconds 5 "
        "--out drive.csv",
        formatter_class=raw,
    )
    drive.add_argument("--start", type=_triple, required=True, metavar="X,Y,THETA")
    drive.add_argument("--cmd", type=_pair, required=True, metavar="V,W")
    drive.add_argument("--dt", type=number_in(1.0, " s"), default=0.1, help="step (s, default 0.1)")
    drive.add_argument(
        "--seconds", type=number_in(100_000, " s"), required=True, help="duration (s)"
    )
    drive.add_argument("--out", type=Path, required=True, help="output CSV")
    drive.add_argument("--maze", default=None, help="built-in name or maze file (default none)")
    mazes.set_defaults(func=_cmd_mazes, precision=NETWORKS)
    show.set_defaults(func=_cmd_show_maze, precision=NETWORKS, writes="file")
    sonar.set_defaults(func=_cmd_sonar, precision=NETWORKS, writes="file")
    drive.set_defaults(func=_cmd_drive, precision=NETWORKS, writes="file")


def _cmd_mazes(args: argparse.Namespace) -> int:
    from mbn.world.mazes.builtin import describe_builtins

    if getattr(args, "mazes_action", None) is not None:
        return int(args.func(args))
    items = describe_builtins()
    if args.json:
        print(json_text({name: text for name, text in items}))
        return 0
    width = max(len(name) for name, _ in items)
    for name, text in items:
        print(f"{name:<{width}}  {text}")
    return 0


def _parameter(fam: Any, key: str, text: str) -> Any:
    """A ``--set`` value, typed as the family's parameter ``key``."""
    from mbn.world.mazes.families import parameter_names

    if key not in parameter_names():
        raise MbnInputError(
            f"--set {key}: unknown parameter (known: {', '.join(parameter_names())})"
        )
    current = getattr(fam, key)
    parts = [p.strip() for p in text.split(",") if p.strip()]
    try:
        if isinstance(current, tuple):
            kind = type(current[0]) if current else (str if key.endswith("rules") else int)
            return tuple(kind(p) for p in parts)
        return type(current)(text)
    except ValueError:
        raise MbnInputError(f"--set {key}={text}: not a valid {key}") from None


def _cmd_mazes_generate(args: argparse.Namespace) -> int:
    from mbn.io import atomic_open
    from mbn.world.mazes import families

    fam = families.family(args.family)
    changes = {}
    for item in args.set:
        key, sep, value = item.partition("=")
        if not sep:
            raise MbnInputError(f"--set {item}: expected KEY=VALUE")
        changes[key.strip()] = _parameter(fam, key.strip(), value)
    if changes:
        fam = fam.replace(name=f"{fam.name}-custom", **changes)
    text = families.generate_text(fam, args.seed)
    if changes:
        text = (
            "".join(
                f"; --set {k}={','.join(map(str, v)) if isinstance(v, tuple) else v}\n"
                for k, v in changes.items()
            )
            + text
        )
    with atomic_open(args.out) as handle:
        handle.write(text)
    maze = families.generate(fam, args.seed)
    info = families.describe(maze)
    print(
        f"{args.out}: {maze.name} ({families.split_of(args.seed, fam)} split), "
        f"{info['shape'][0]} x {info['shape'][1]} cells, {info['plus_crossings']} plus, "
        f"{info['t_junctions']} T, {info['corners']} corners, {info['dead_ends']} dead ends, "
        f"{info['loops']} loops, {len(maze.tiles)} tiles, {info['starts']} starts"
    )
    return 0


def _cmd_mazes_families(args: argparse.Namespace) -> int:
    from mbn.world.mazes import families

    splits = {k: [r.start, r.stop - 1] for k, r in families.SPLITS.items()}
    data = {
        "families": {name: f.to_dict() for name, f in families.FAMILIES.items()},
        "splits": splits,
        "zero_shot": {k: list(v) for k, v in families.ZERO_SHOT.items()},
        "looked_into": {k: list(v) for k, v in families.LOOKED_INTO.items()},
    }
    if args.json:
        print(json_text(data))
        return 0
    for name, fam in families.FAMILIES.items():
        print(f"{name}: {fam.doc}")
        for key, value in fam.to_dict().items():
            if key not in ("name", "doc"):
                print(f"    {key} = {value}")
    for split, (a, b) in splits.items():
        print(f"split {split}: seeds {a}-{b}")
    for name, seeds in families.LOOKED_INTO.items():
        print(
            f"looked into, moved from {name}'s test split to its validation: "
            f"{', '.join(map(str, seeds))} (its test split takes as many seeds after {b} instead)"
        )
    for name, suite in families.ZERO_SHOT.items():
        print(f"zero-shot suite of {name} ({name}/zero-shot): {', '.join(suite)}")
    return 0


def _cmd_show_maze(args: argparse.Namespace) -> int:
    from mbn.viz.maze import save_maze_png
    from mbn.world.mazes.load import load_maze, maze_file_grid_shape

    shape = maze_file_grid_shape(args.maze)  # before reading it: a quick look at its lines
    if shape is not None:
        rows, cols = shape
        if rows * cols > MAX_DRAW_CELLS:
            raise MbnInputError(
                f"{args.maze}: a grid of {rows} x {cols} cells; show-maze draws grids of at most "
                f"{MAX_DRAW_CELLS:,} cells (1000 x 1000)"
            )
    maze = load_maze(args.maze)
    save_maze_png(maze, args.out)
    print(f"wrote {args.out}")
    return 0


def _cmd_sonar(args: argparse.Namespace) -> int:
    import jax
    import jax.numpy as jnp

    from mbn.io import read_csv_columns, write_csv_atomic
    from mbn.world.engine import cast, compile_mazes, maze_constants, window_words
    from mbn.world.geometry import sonar_rays
    from mbn.world.mazes.load import load_maze

    maze = load_maze(args.maze)
    cols = read_csv_columns(args.poses, ["x", "y", "theta"])
    poses = np.stack([cols["x"], cols["y"], cols["theta"]], -1)
    if len(poses) == 0:
        raise MbnInputError(f"{args.poses}: no poses")
    origins, _ = sonar_rays(poses)
    for row, sensor_origins in enumerate(np.asarray(origins)):
        if not all(maze.is_free(float(x), float(y)) for x, y in sensor_origins):
            raise MbnInputError(
                f"{args.poses}:{row + 2}: pose {tuple(float(v) for v in poses[row])} puts a sonar "
                f"inside a wall of {maze.name!r}"
            )
    world = compile_mazes([maze])

    @jax.jit
    def read(p: jax.Array) -> jax.Array:
        mc = maze_constants(world, jnp.zeros(p.shape[0], jnp.int32))
        words, ci, cj = window_words(world, mc, p[:, 0], p[:, 1])
        o, a = sonar_rays(p)
        return cast(world, mc, words, ci, cj, o[..., 0], o[..., 1], a)

    ranges = np.asarray(read(jnp.asarray(poses, jnp.float64)))
    header = ["x", "y", "theta"] + [f"s{i:02d}" for i in range(16)]
    write_csv_atomic(args.out, header, np.concatenate([poses, ranges], -1))
    print(f"wrote {len(poses)} rows to {args.out}")
    return 0


def _cmd_drive(args: argparse.Namespace) -> int:
    import jax
    import jax.numpy as jnp

    from mbn.io import atomic_open
    from mbn.world.engine import compile_mazes
    from mbn.world.geometry import collides
    from mbn.world.mazes.load import load_maze
    from mbn.world.mazes.model import Maze
    from mbn.world.rollout import RolloutConfig, rollout

    steps = round(args.seconds / args.dt)
    if steps < 1 or abs(steps * args.dt - args.seconds) > 1e-9 * max(1.0, args.seconds):
        raise MbnInputError(
            f"--seconds {args.seconds} is not a whole number of --dt {args.dt} steps"
        )
    if steps > 1_000_000:
        raise MbnInputError(f"{steps} steps is too many (at most 1000000)")
    start = np.array(args.start, dtype=np.float64)
    if args.maze is None:
        x, y = start[0], start[1]
        far = 10.0 + args.seconds * 0.5 * 2
        maze = Maze(
            "empty",
            walls=np.array([[x + far, x + far + 1.0, y + far, y + far + 1.0]]),
            bounds=(x - far, x + far + 1.0, y - far, y + far + 1.0),
            outside_is_wall=False,
        )
    else:
        maze = load_maze(args.maze)
        if bool(np.asarray(collides(jnp.asarray(start[None]), maze.solid_rects()))[0]):
            raise MbnInputError(f"--start {args.start}: the robot's body overlaps a wall")
    world = compile_mazes([maze])
    v_cmd, w_cmd = args.cmd

    def constant(state: Any, obs: Any) -> tuple[Any, tuple[Any, Any]]:
        return state, (jnp.asarray(v_cmd), jnp.asarray(w_cmd))

    # in chunks of at most _DRIVE_CHUNK moves, each from the last pose of the one before (the
    # constant command has no state): memory stays bounded whatever the duration
    chunk = min(steps, _DRIVE_CHUNK)
    config = RolloutConfig(steps=chunk + 1, dt=args.dt, record_every=1)
    run = jax.jit(
        lambda p: rollout(world, constant, jnp.zeros(1), p, jnp.zeros(1, jnp.int32), config)
    )
    n_stalled = 0
    here = jnp.asarray(start[None])
    with atomic_open(args.out) as handle:
        handle.write("step,t,x,y,theta,v,w,stall\n")
        for base in range(0, steps, chunk):
            tr = run(here).trajectory
            assert tr is not None
            pose = np.asarray(tr.pose[0])  # sample k: the pose after base + k moves
            stalled = np.asarray(tr.stalled[0]).astype(int)
            v = np.concatenate([[0.0], np.asarray(tr.v[0])[:-1]])  # the move that led to it
            w = np.concatenate([[0.0], np.asarray(tr.w[0])[:-1]])
            first = 0 if base == 0 else 1
            last = min(chunk, steps - base)
            n_stalled += int(stalled[1 : last + 1].sum())
            lines = []
            for k in range(first, last + 1):
                x, y, th = (repr(float(c)) for c in pose[k])
                lines.append(
                    f"{base + k},{(base + k) * args.dt!r},{x},{y},{th},{float(v[k])!r},"
                    f"{float(w[k])!r},{int(stalled[k])}\n"
                )
            handle.write("".join(lines))
            here = jnp.asarray(pose[last][None])
    print(f"wrote {steps + 1} rows to {args.out} ({n_stalled} stalled moves)")
    return 0
