"""The network commands of ``mbn``: ``mul train|eval|report`` (the multiplier CTRNN, paper
2.1) and ``pnn check`` (the emulation check of the paper's interpreter, paper section 2). They
compute in float64 (:mod:`mbn.precision`)."""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from mbn.cli.args import int_in, number_in
from mbn.cli.args import seed as seed_type
from mbn.errors import MbnInputError
from mbn.io import json_text
from mbn.precision import NETWORKS

__all__ = ["EPILOG", "add_commands"]

EPILOG = """\
  mbn mul train --out runs/mul.json           train a 3-neuron multiplier by BPTT
  mbn mul report --params runs/mul.json       its error map (PNG) and metrics
  mbn mul eval --pairs in.csv --out out.csv   products of the pairs in a CSV (x1,x2)
  mbn pnn check --json                        emulation check of the paper's RF/LF interpreter
"""


def add_commands(sub: Any, parser_class: type[argparse.ArgumentParser]) -> None:
    """Add ``mul`` and ``pnn`` to the ``mbn`` sub-parsers."""
    mul = sub.add_parser(
        "mul",
        help="the multiplier CTRNN (paper 2.1)",
        description="Train, evaluate and inspect multiplier CTRNNs.",
        epilog="examples:\n"
        "  mbn mul report --out mul.png    the shipped 3-neuron multiplier: error map and metrics\n"
        "  mbn mul train --neurons 3 --seed 0 --out runs/mul.json\n"
        "  mbn mul eval --pairs pairs.csv --out products.csv",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    mul_sub = mul.add_subparsers(dest="mul_command", required=True, parser_class=parser_class)

    train = mul_sub.add_parser(
        "train",
        help="train a multiplier by BPTT",
        description="Train a multiplier CTRNN by backpropagation through time from many random "
        "restarts at once and keep the best by validation (paper 2.1). Writes the parameters and "
        "a metrics block as JSON.",
        epilog="example:\n  mbn mul train --neurons 3 --seed 0 --out runs/mul.json",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    train.add_argument(
        "--neurons",
        type=int_in(1, 64),
        default=3,
        help="neurons of the multiplier (default 3, the paper's)",
    )
    train.add_argument("--seed", type=seed_type, default=0, help="random seed (default 0)")
    train.add_argument(
        "--restarts",
        type=int_in(1, 100_000),
        default=None,
        help="restarts trained in parallel (default: the recipe's)",
    )
    train.add_argument(
        "--iterations",
        type=int_in(1, 10_000_000),
        default=None,
        help="Adam iterations (default: the recipe's)",
    )
    train.add_argument(
        "--out",
        type=Path,
        default=Path("multiplier.json"),
        help="output JSON file (default multiplier.json)",
    )
    train.add_argument("--quiet", action="store_true", help="no progress bar")
    train.set_defaults(func=_cmd_mul_train, precision=NETWORKS, writes="file")

    ev = mul_sub.add_parser(
        "eval",
        help="multiply the pairs of a CSV file",
        description="Read a CSV with columns x1,x2 (values in [0, 1]) and write x1,x2,output.",
        epilog="example:\n  mbn mul eval --pairs pairs.csv --out products.csv",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ev.add_argument("--pairs", type=Path, required=True, help="input CSV with columns x1,x2")
    ev.add_argument("--out", type=Path, required=True, help="output CSV (x1,x2,output)")
    ev.add_argument(
        "--params",
        type=Path,
        default=None,
        help="multiplier JSON (default: the shipped 3-neuron multiplier)",
    )
    ev.set_defaults(func=_cmd_mul_eval, precision=NETWORKS, writes="file")

    rep = mul_sub.add_parser(
        "report",
        help="error heat map (PNG) and metrics",
        description="Draw the absolute and relative error of a multiplier over (0,1)^2 as a PNG "
        "and print its metrics (validation pairs, dense grid, fixed-point check).",
        epilog="example:\n  mbn mul report --params runs/mul.json --out runs/mul.png",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    rep.add_argument(
        "--params",
        type=Path,
        default=None,
        help="multiplier JSON (default: the shipped 3-neuron multiplier)",
    )
    rep.add_argument(
        "--out",
        type=Path,
        default=Path("multiplier_error.png"),
        help="output PNG (default multiplier_error.png)",
    )
    rep.add_argument(
        "--seed",
        type=seed_type,
        default=None,
        help="seed of the validation pairs (default: the one the file records)",
    )
    rep.add_argument("--json", action="store_true", help="print the metrics as JSON")
    rep.set_defaults(func=_cmd_mul_report, precision=NETWORKS, writes="file")

    pnn = sub.add_parser(
        "pnn",
        help="programmable networks (paper section 2)",
        description="Programmable-network tools.",
        epilog="example:\n"
        "  mbn pnn check    how closely the interpreter of the paper's RF and LF emulates them",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    pnn_sub = pnn.add_subparsers(dest="pnn_command", required=True, parser_class=parser_class)
    check = pnn_sub.add_parser(
        "check",
        help="emulation check of the paper's RF/LF interpreter",
        description="Build the interpreter of the paper's published RF network with the three "
        "connections in which RF and LF differ programmable; drive the original networks and the "
        "interpreter (with each network's program) with random piecewise-constant inputs in "
        "[0,1]^3; report the largest difference over time of the firing rates of neurons 2 and "
        "3, in exact-product mode and with the multiplier.",
        epilog="example:\n  mbn pnn check --json",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    check.add_argument("--json", action="store_true", help="print one JSON object")
    check.add_argument(
        "--sequences",
        type=int_in(1, 100_000),
        default=200,
        help="random input sequences per program (default 200)",
    )
    check.add_argument(
        "--seconds",
        type=number_in(3_600, " s"),
        default=20.0,
        help="length of each sequence in seconds (default 20)",
    )
    check.add_argument("--seed", type=seed_type, default=0, help="random seed (default 0)")
    check.add_argument(
        "--tau-ratio",
        type=_tau_ratio,
        default=0.1,
        help="multiplier time constant / network time constant (default 0.1, the paper's); the "
        "step is a tenth of the multipliers' time constant",
    )
    check.add_argument(
        "--from-rest",
        action="store_true",
        help="start every run at y = 0 instead of the settled state of the first input",
    )
    check.add_argument(
        "--params",
        type=Path,
        default=None,
        help="multiplier JSON (default: the shipped 3-neuron multiplier)",
    )
    check.set_defaults(func=_cmd_pnn_check, precision=NETWORKS)


#: ``pnn check --tau-ratio``'s range: the step is a tenth of the multipliers' time constant, so
#: 0.001 makes it 5e-5 s, 100 times the paper's (400 000 steps a 20 s sequence); below, the steps
#: of a sequence grow without bound (1e-300: more than an array can hold).
TAU_RATIO_RANGE = (1e-3, 10.0)


def _tau_ratio(text: str) -> float:
    """``--tau-ratio``: a number in :data:`TAU_RATIO_RANGE`."""
    low, high = TAU_RATIO_RANGE
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not low <= value <= high:  # also NaN
        raise argparse.ArgumentTypeError(f"must be in [{low:g}, {high:g}], got {text}")
    return value


@contextlib.contextmanager
def _progress(enabled: bool, description: str) -> Iterator[Any]:
    if not enabled:
        yield None
        return
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(),
        transient=True,
    ) as progress:
        yield (progress, progress.add_task(description, total=None))


def _cmd_mul_train(args: argparse.Namespace) -> int:
    import dataclasses

    import jax

    from mbn.networks.multiplier import save_multiplier
    from mbn.networks.multiplier_train import recipe, train_stages

    stages = list(recipe(args.neurons))
    if args.restarts is not None:
        stages[0] = dataclasses.replace(stages[0], num_restarts=args.restarts)
    if args.iterations is not None:
        stages = [dataclasses.replace(st, num_iterations=args.iterations) for st in stages]
    start = time.perf_counter()
    with _progress(not args.quiet and sys.stderr.isatty(), "training multiplier") as bar:

        def report(done: int, total: int) -> None:
            if bar is not None:
                bar[0].update(bar[1], completed=done, total=total)

        mul, metrics = train_stages(jax.random.key(args.seed), tuple(stages), progress=report)
    metrics["training"]["seed"] = args.seed
    metrics["training"]["wall_seconds"] = round(time.perf_counter() - start, 2)
    save_multiplier(args.out, mul, metrics)
    _print_metrics(metrics, header=f"wrote {args.out}")
    return 0


def _print_metrics(metrics: dict[str, Any], header: str | None = None) -> None:
    if header:
        print(header)
    fp = metrics["fixed_point"]
    print(
        f"  validation pairs within 5 %:        {metrics['fraction_within_5pct']:.0%}"
        f" of {metrics['num_validation_pairs']}"
    )
    print(f"  max relative error (product>=0.05): {metrics['max_rel_error_product_ge_0.05']:.2%}")
    print(f"  max relative error (all pairs):     {metrics['max_rel_error']:.2%}")
    print(
        f"  max abs error, {metrics['grid_points_per_axis']}x"
        f"{metrics['grid_points_per_axis']} grid:     {metrics['max_abs_error_grid']:.4f}"
    )
    print(f"  mean abs error, grid:               {metrics['mean_abs_error_grid']:.4f}")
    print(
        f"  fixed point (|out(2T)-out(T)|, |out(h/10)-out(h)|): "
        f"{fp['max_abs_diff_2T']:.1e}, {fp['max_abs_diff_fine_step']:.1e} -> "
        f"{'ok' if fp['passed'] else 'FAILED'}"
    )
    training = metrics.get("training", {})
    if "train_seconds" in training:
        print(f"  training: {training['train_seconds']:.1f} s, seed {training.get('seed')}")


def _load_mul(path: Path | None) -> Any:
    from mbn.networks.multiplier import load_default, load_multiplier

    return load_default() if path is None else load_multiplier(path)


def _cmd_mul_eval(args: argparse.Namespace) -> int:
    import numpy as np

    from mbn.io import read_csv_columns, write_csv_atomic
    from mbn.networks.multiplier import multiply

    mul = _load_mul(args.params)
    columns = read_csv_columns(args.pairs, ["x1", "x2"])
    pairs = np.stack([columns["x1"], columns["x2"]], axis=-1)
    outside = np.nonzero(((pairs < 0) | (pairs > 1)).any(axis=1))[0]
    if outside.size:
        raise MbnInputError(
            f"{args.pairs}: data row {outside[0] + 1}: x1, x2 must be in [0, 1], got "
            f"{pairs[outside[0]].tolist()}"
        )
    output = np.asarray(multiply(mul, pairs)) if len(pairs) else np.zeros(0)
    if not np.all(np.isfinite(output)):
        where = args.params or "the shipped multiplier"
        raise MbnInputError(
            f"{where}: its output is not finite for some pairs (the weights make the integration "
            "overflow); nothing written"
        )
    write_csv_atomic(args.out, ["x1", "x2", "output"], np.column_stack([pairs, output]))
    print(f"wrote {args.out} ({len(pairs)} pairs)")
    return 0


def _cmd_mul_report(args: argparse.Namespace) -> int:
    import jax

    from mbn.networks.multiplier import (
        evaluate,
        load_default,
        recorded_seed,
        shipped_metrics,
        validation_pairs,
    )
    from mbn.viz.multiplier import plot_multiplier_error

    if args.params is None:
        mul = load_default()
        recorded = recorded_seed({"metrics": shipped_metrics()}, "the shipped multiplier")
    else:
        from mbn.io import read_json
        from mbn.networks.multiplier import multiplier_from_dict

        data = read_json(args.params)
        mul = multiplier_from_dict(data, where=str(args.params))
        recorded = recorded_seed(data, str(args.params))
    seed = args.seed
    if seed is None:
        seed = recorded if recorded is not None else 0
    # Same derivation of the validation key as in training: key(seed) -> split -> second half.
    _, k_val = jax.random.split(jax.random.key(seed))
    metrics = evaluate(mul, validation_pairs(k_val))
    metrics["validation_seed"] = seed
    plot_multiplier_error(mul, args.out, metrics=metrics)
    if args.json:
        print(json_text(metrics, indent=2))
    else:
        _print_metrics(metrics, header=f"wrote {args.out}")
    return 0


def _cmd_pnn_check(args: argparse.Namespace) -> int:
    import jax

    from mbn.networks.emulation import EmulationConfig, published_check
    from mbn.notation import connection_name

    mul = _load_mul(args.params)
    defaults = EmulationConfig()
    config = EmulationConfig(
        num_sequences=args.sequences,
        seconds=args.seconds,
        tau_ratio=args.tau_ratio,
        dt=defaults.dt * args.tau_ratio / defaults.tau_ratio,
        start="rest" if args.from_rest else "settled",
    )
    result = published_check(jax.random.key(args.seed), mul, config)
    if args.json:
        print(json_text({k: result[k] for k in ("exact", "trained", "num_sequences")}))
        return 0
    print(
        "interpreter of the published RF with programmable "
        + ", ".join(
            f"{connection_name(c['connection'])} in [{c['min']:.4g}, {c['max']:.4g}]"
            for c in result["connections"]
        )
    )
    print(
        f"  {result['interpreter_neurons']} neurons; programs RF {result['programs'][0]}, "
        f"LF {result['programs'][1]}"
    )
    start = "rest (y = 0)" if args.from_rest else f"the settled state ({config.settle:g} s)"
    print(
        f"  {result['num_sequences']} sequences of {args.seconds:g} s (both programs), "
        f"multipliers at tau x {config.tau_ratio:g}, dt {config.dt:g} s, from {start}"
    )
    print(f"  exact product:  max |diff| = {result['exact']['max_abs_output_diff']:.2e}")
    t = result["trained"]
    print(
        f"  multiplier:     median {t['median_max_abs_output_diff']:.4f}, "
        f"95th percentile {t['p95_max_abs_output_diff']:.4f}, "
        f"max {t['max_max_abs_output_diff']:.4f}"
    )
    for name, part in zip(("RF", "LF"), result["per_program"], strict=True):
        print(
            f"    {name} program:   median {part['median_max_abs_output_diff']:.4f}, "
            f"95th percentile {part['p95_max_abs_output_diff']:.4f}"
        )
    return 0
