"""Where does a three-behaviour MBN lose trials its programs pass alone? A probe
(docs/behaviours.md, "In the three-tile mazes placed again").

Runs ``mbn evaluate --behavior tiles`` on an MBN controller file (``controllers/mbn3.json`` of
``mbn run new-behaviours``, or another code-PM MBN given with ``--controller``, such as
``controllers/contest_three-behaviours_programs.json`` of ``mbn run programs-vs-dynamics``)
three ways:

* ``as-is``: the file as it is;
* ``calibrated``: the readout replaced by ``P @ inv(C)`` (``P``: its programs, ``C``: the codes
  the program module latches after each tile kind, ``latched_codes`` of ``stages/mbn3.json``
  for ``mbn3.json``, else computed from the file's program module as the stage computes them),
  so that a latched code sends its program exactly instead of a blend;
* ``snapped``: the program module's code replaced, every step, by the one-hot vector of its
  largest neuron, so that the program switches at once and exactly.

The last two change the controller in memory only (the file is not written, and its readout
would not pass the file's check: the calibrated columns leave [0, 1], by a few thousandths where
the codes are near one-hot and far more where they are not).

Usage: python scripts/probe_mbn_switch.py RUN_DIR [--controller FILE] [--maze tiles3_heldout]
[--repeats 17]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run", type=Path, help="a run folder (new-behaviours by default)")
    parser.add_argument(
        "--controller", type=Path, default=None, help="default: RUN/controllers/mbn3.json"
    )
    parser.add_argument("--maze", default="tiles3_heldout")
    parser.add_argument("--repeats", default="17")
    parser.add_argument("--seed", default="2")
    parser.add_argument("--seconds", default="120")
    parser.add_argument("--mode", choices=("as-is", "calibrated", "snapped"), default=None)
    args = parser.parse_args(argv)
    if args.mode is None:  # each mode in its own process: the patches below are global
        import subprocess

        for mode in ("as-is", "calibrated", "snapped"):
            cmd = [sys.executable, __file__, str(args.run), "--mode", mode, "--maze", args.maze]
            if args.controller is not None:
                cmd += ["--controller", str(args.controller)]
            cmd += ["--repeats", args.repeats, "--seed", args.seed, "--seconds", args.seconds]
            out = subprocess.run(cmd, capture_output=True, text=True, check=False)
            lines = out.stdout.splitlines()
            if mode == "as-is":
                print(*[line for line in lines if line.startswith("latched codes")], sep="\n")
            total = [line for line in lines if "total:" in line]
            print(f"{mode:>10}: {total[-1].strip() if total else out.stderr.strip()[-300:]}")
        return 0

    import jax
    import jax.numpy as jnp

    import mbn.control.mbn as control
    import mbn.controllers.load as load
    from mbn.cli.main import main as mbn_main

    controller = args.controller or args.run / "controllers" / "mbn3.json"
    pm = json.loads(controller.read_text())["program_module"]
    readout = np.array(pm["readout"])
    if args.controller is None:
        stage = json.loads((args.run / "stages" / "mbn3.json").read_text())
        codes = np.array([stage["latched_codes"][r] for r in pm["tile_rules"]]).T
    else:
        codes = latched_codes(controller)
    print(f"latched codes (columns: tile kinds): {np.round(codes, 3).tolist()}")
    made = control.make_mbn_controller
    rate = control.firing_rate

    def calibrated(**kw):  # type: ignore[no-untyped-def]
        return made(**{**kw, "readout": readout @ np.linalg.inv(codes)})

    def snapped(network, y):  # type: ignore[no-untyped-def]
        r = rate(network, y)
        return jax.nn.one_hot(jnp.argmax(r, axis=-1), r.shape[-1], dtype=r.dtype)

    if args.mode == "calibrated":
        load.make_mbn_controller = calibrated  # type: ignore[assignment]
    elif args.mode == "snapped":
        control.firing_rate = snapped  # type: ignore[assignment]
    cmd = ["evaluate", "--controller", str(controller), "--maze", args.maze, "--behavior"]
    cmd += ["tiles", "--repeats", args.repeats, "--seed", args.seed, "--seconds", args.seconds]
    return mbn_main(cmd)


def latched_codes(controller: Path) -> np.ndarray:
    """The code the file's program module latches after a tile of each kind (columns), as
    ``evolve_code_pm`` computes them (the program reward's viewing time)."""
    import jax
    import jax.numpy as jnp

    from mbn.controllers import read_controller_spec
    from mbn.experiments.stages.mbn3 import latched_codes as latched

    spec = read_controller_spec(controller)
    pm = jax.tree.map(lambda a: jnp.asarray(np.asarray(a, np.float64)), spec.program_module)
    columns = latched(pm, len(spec.tile_rules))
    if any(c is None for c in columns):
        raise SystemExit(f"{controller}: the program module does not settle after a tile")
    return np.stack(columns, axis=1)


if __name__ == "__main__":
    sys.exit(main())
