"""The report of ``mbn reproduce``: figures, ``report.md`` and a self-contained ``report.html``.

The figures go to ``figures/`` (PNG, and a GIF of the MBN); ``report.md`` links them,
``report.html`` embeds them (base64), so it can be mailed or opened anywhere. Both are built from
the same list of sections.
"""

from __future__ import annotations

import base64
import html
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import jax
import numpy as np

from mbn.io import atomic_open

__all__ = ["write_report"]


@dataclass
class _Section:
    title: str
    text: list[str] = field(default_factory=list)
    table: tuple[list[str], list[list[str]]] | None = None
    images: list[tuple[str, str]] = field(default_factory=list)  # (file under out, caption)
    status: list[bool | None] | None = None  # per table row: pass/fail colouring


def _figure(figsize: tuple[float, float]) -> Any:
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    return Figure(figsize=figsize)


def _save(fig: Any, path: Path, dpi: int = 100) -> None:
    with atomic_open(path, "wb") as handle:
        fig.savefig(handle, format="png", dpi=dpi, bbox_inches="tight")


# ---------------------------------------------------------------------------------------------
# Figures
# ---------------------------------------------------------------------------------------------


def _de_curves(stages: dict[str, Any], path: Path) -> None:
    fig = _figure((11, 7.5))
    axes = fig.subplots(2, 2)
    for ax, (name, title) in zip(
        (axes[0, 0], axes[1, 0], axes[1, 1]),
        (("rf", "RF (12 genes)"), ("lf", "LF (3 genes)"), ("pm", "PM (program module)")),
        strict=True,
    ):
        h = stages[name]["history"]
        g = np.arange(len(h["best"]))
        chosen = stages[name].get("chosen_restart")
        for r, other in enumerate(stages[name].get("restarts", [])):
            if r != chosen:
                ax.plot(
                    np.arange(len(other["history"]["best"])),
                    other["history"]["best"],
                    color="C0",
                    alpha=0.35,
                    lw=1,
                    label=f"best, restart {r + 1} (not kept)",
                )
        ax.plot(g, h["best"], label="best", color="C0")
        ax.plot(g, h["mean"], label="population mean", color="C1", alpha=0.8)
        if name == "pm":
            ax.axhline(stages[name]["max_fitness"], color="grey", ls="--", lw=1, label="maximum")
        ax.set_title(f"{title}: DE fitness")
        ax.set_xlabel("generation")
        ax.set_ylabel("fitness")
        ax.legend(loc="lower right", fontsize=8)
    ax = axes[0, 1]
    rows = stages["lf_search"]["triples"]
    chosen = stages["lf_search"]["chosen"]
    fit = [r["best_fitness"] for r in rows]
    robust = [r.get("robust_fitness", np.nan) for r in rows]
    labels = [", ".join(_short(c) for c in r["connections"]) for r in rows]
    colors = ["C2" if r["connections"] == chosen else "C7" for r in rows]
    y = np.arange(len(rows))
    ax.barh(y, robust, color=colors, height=0.6, label="choice score: perturbed copies, corners")
    ax.barh(y, fit, color="none", edgecolor="k", lw=0.8, zorder=3, label="search's best fitness")
    ax.set_yticks(y, labels, fontsize=6)
    ax.invert_yaxis()
    ax.set_xlabel("left-rule fitness")
    ax.legend(loc="lower right", fontsize=7)
    ax.set_title("LF: which 3 connections to re-evolve (green: chosen)")
    fig.tight_layout()
    _save(fig, path)


def _short(conn: str) -> str:
    from mbn.experiments.reproduce import _paper_name

    return _paper_name(conn)


def _trajectories(repro: Any, stages: dict[str, Any], out: Path) -> list[tuple[str, str]]:
    from mbn.experiments.reproduce import TESTED
    from mbn.viz.render import plot_episodes
    from mbn.world.mazes.load import load_maze

    trajs = repro.test_trajectories()
    maze = load_maze(repro.settings.test_maze)
    details = stages["tests"]["details"]
    images = []
    for name, rule in TESTED:
        traj = trajs[name]
        d = details[name]
        n = len(d["success"])
        titles = [
            f"start {k + 1}: {'ok' if d['success'][k] else 'FAIL'} "
            f"({d['correct'][k]}/{d['judged'][k]}, stall {d['stall'][k]:.1%})"
            for k in range(n)
        ]
        t = stages["tests"]["tests"][name]
        fig = plot_episodes(
            maze,
            traj,
            list(range(n)),
            titles=titles,
            ncols=5,
            title=f"{name} (rule: {rule}) in {maze.name}: {t['successes']}/{t['trials']}",
        )
        file = f"figures/trajectories_{name}.png"
        _save(fig, out / file, dpi=70)
        images.append((file, f"{name}: the paper's protocol, one panel per start mark"))
    return images


def _mbn_recording(repro: Any) -> tuple[Any, Any, Any, int]:
    """The MBN from the test maze's start marks, recorded every step with its state."""
    from mbn.controllers import make_controller, read_controller_spec
    from mbn.experiments.trials import TrialGroup, TrialSpec, run_trial_groups
    from mbn.world.mazes.load import load_maze

    spec = read_controller_spec(repro.out / "controllers" / "mbn.json")
    loaded = make_controller(spec, None, where="mbn.json")
    maze = load_maze(repro.settings.test_maze)
    group = TrialGroup("mbn", 0, TrialSpec(behavior="tiles", initial="none"), loaded.initial_state)
    verdicts, result, _, _ = run_trial_groups(
        [maze],
        [group],
        loaded.controller,
        seconds=repro.settings.mbn_seconds,
        dt=loaded.dt,
        sensors=loaded.sensors,
        camera=loaded.camera,
        record_every=1,
        record_controller=True,
    )
    traj = result.trajectory
    assert traj is not None
    tile = np.asarray(traj.tile)
    # the episode with most changes of the tile in force (a success first), to show switching
    changes = (np.diff(tile, axis=1) != 0).sum(1) + 100 * np.asarray(verdicts["mbn"]["success"])
    return spec, maze, traj, int(np.argmax(changes))


def _mbn_traces(spec: Any, traj: Any, b: int, path: Path) -> None:
    from mbn.networks.ctrnn import firing_rate

    state = traj.controller
    pick = lambda tree: jax.tree.map(lambda a: np.asarray(a[b]), tree)  # noqa: E731
    pm, pm_y, im, im_y = (pick(x) for x in state)
    program = np.asarray(firing_rate(pm, pm_y))[:, list(spec.program_neurons)]
    n0 = spec.interpreter_spec.interpreter.num_original
    rates = np.asarray(firing_rate(im, im_y))[:, :n0]
    t = np.asarray(traj.t)
    camera = np.asarray(traj.camera[b])
    tile = np.asarray(traj.tile[b])
    fig = _figure((11, 7))
    ax = fig.subplots(4, 1, sharex=True, gridspec_kw={"height_ratios": [1, 2, 2, 1.4]})
    ax[0].step(t, camera, where="post", color="C7", label="camera (tile in view)")
    ax[0].step(t, tile, where="post", color="C3", lw=2, label="tile in force (driven over)")
    ax[0].set_yticks([0, 1, 2], ["none", "1 colour", "2 colours"])
    ax[0].legend(loc="upper right", fontsize=8)
    names = [str(c) for c in spec.interpreter_spec.interpreter.connections]
    progs = spec.interpreter_spec.programs
    for k in range(program.shape[1]):
        ax[1].plot(t, program[:, k], label=f"program {k + 1} ({names[k]})", color=f"C{k}")
    for name, style in (("right", ":"), ("left", "--")):
        for k, v in enumerate(progs[name]):
            ax[1].axhline(v, color=f"C{k}", ls=style, lw=0.8, alpha=0.6)
    ax[1].set_ylabel("PM output")
    ax[1].set_ylim(-0.05, 1.05)
    ax[1].legend(loc="center right", fontsize=8, title="dotted: RF program, dashed: LF", ncol=3)
    for k in range(n0):
        ax[2].plot(t, rates[:, k], label=f"neuron {k + 1}", color=f"C{k + 3}")
    ax[2].set_ylabel("IM firing rate")
    ax[2].legend(loc="upper right", fontsize=8, ncol=3)
    ax[3].plot(t, np.asarray(traj.v[b]), label="v (m/s)", color="C0")
    ax[3].plot(t, np.asarray(traj.w[b]), label="omega (rad/s)", color="C1")
    ax[3].set_xlabel("time (s)")
    ax[3].legend(loc="upper right", fontsize=8, ncol=2)
    switches = [int(i) + 1 for i in np.flatnonzero(np.diff(tile) != 0)]
    for a in ax:
        for i in switches:
            a.axvline(t[i], color="C3", lw=0.8, alpha=0.5)
    ax[0].set_title(
        f"MBN from start mark {b + 1}: camera, program, interpreter and motors "
        "(red lines: tile in force changes)"
    )
    fig.tight_layout()
    _save(fig, path)


def _mbn_gif(spec: Any, maze: Any, traj: Any, b: int, path: Path) -> None:
    from mbn.viz.render import animate_episode

    animate_episode(
        maze,
        np.asarray(traj.pose[b]),
        path,
        ranges=np.asarray(traj.ranges[b]),
        sonars=spec.interpreter_spec.sensors.sonars,
        camera=np.asarray(traj.camera[b]),
        tile=np.asarray(traj.tile[b]),
        stalled=np.asarray(traj.stalled[b]),
        t=np.asarray(traj.t),
        fps=15.0,
        max_frames=150,
        dpi=60,
        title=f"MBN from start mark {b + 1}",
        camera_fov_deg=spec.camera.fov_deg,
        camera_range=spec.camera.range,
    )


# ---------------------------------------------------------------------------------------------
# Sections
# ---------------------------------------------------------------------------------------------


def _sections(repro: Any, results: dict[str, Any], images: dict[str, Any]) -> list[_Section]:
    from mbn.experiments.reproduce import TESTED

    s = results["stages"]
    tests = results["tests"]
    secs = []
    quick = " This is a **quick** smoke run: tiny budgets, the figures are not the paper's." * bool(
        results["quick"]
    )
    v = results["versions"]
    secs.append(
        _Section(
            "Run",
            [
                f"Seed {results['seed']} (derived seeds: "
                + ", ".join(f"{k} {val}" for k, val in results["seeds"].items() if k != "seed")
                + f"). mbn {v['mbn']}, JAX {v['jax']}, Python {v['python']} on {v['platform']}."
                + quick,
                "Paper: Montone, Donnarumma & Prevete, *A robotic scenario for programmable "
                "fixed-weight neural networks exhibiting multiple behaviors*, ICANNGA 2011. "
                "Where this run departs from the paper, and why: `docs/reproduce.md`.",
            ],
        )
    )
    claims = results["claims"]
    secs.append(
        _Section(
            "Claims: the paper and this run",
            [f"{sum(c['pass'] for c in claims)} of {len(claims)} claims hold."],
            table=(
                ["claim", "paper", "measured", "criterion", "holds"],
                [
                    [c["claim"], c["paper"], c["measured"], c["criterion"], _yes(c["pass"])]
                    for c in claims
                ],
            ),
            status=[c["pass"] for c in claims],
        )
    )
    proto = s["tests"]["protocol"]
    rows: list[list[str]] = []
    status: list[bool | None] = []
    for name, rule in TESTED:
        for suffix in ("", "_jitter", "_heldout"):
            t = tests[name + suffix]
            rows.append(
                [
                    name + suffix,
                    rule,
                    f"{t['successes']}/{t['trials']}",
                    f"{t['success_rate']:.1%}",
                    f"{t['correct_junctions']}/{t['junctions']}",
                    f"{t['mean_stall_fraction']:.2%}",
                ]
            )
            status.append(None)
    secs.append(
        _Section(
            "Tests",
            [
                f"A trial succeeds when the robot takes the rule's exit at each of its first "
                f"{proto['junctions']} junctions and is stalled at most "
                f"{proto['max_stall_fraction']:.0%} of the time until it leaves the last one; "
                f"{proto['seconds']:g} s per trial ({proto['mbn_seconds']:g} s for the MBN, whose "
                "junctions count from the first tile it drives over). Paper protocol: the start "
                f"marks of `{s['tests']['mazes']['test']}`; `_jitter`: "
                f"{proto['jitter_trials']} (lateral +-0.15 m, along +-0.3 m, heading +-10 deg); "
                f"`_heldout`: maze `{s['tests']['mazes']['heldout']}`, not used in any "
                f"training: {proto['heldout_trials']}.",
                "Interpreter and network take the same branch at every junction in: "
                + "; ".join(
                    f"{k} {a['same_branches']}/{a['trials']} ({a['rate']:.1%})"
                    for k, a in s["tests"]["agreement"].items()
                )
                + ".",
            ],
            table=(["test", "rule", "successes", "rate", "correct junctions", "stall"], rows),
            status=status,
        )
    )
    m = s["multiplier"]
    secs.append(
        _Section(
            "Multiplier",
            [
                f"{m['neurons']}-neuron multiplier, {m['source']}, embedded at tau/10. "
                f"Max |error| {m['metrics']['max_abs_error_grid']:.4f} and mean "
                f"{m['metrics']['mean_abs_error_grid']:.4f} on a 101 x 101 grid of [0, 1]^2."
            ],
            images=[images["multiplier"]],
        )
    )
    lf, im, pm, rf = s["lf"], s["im"], s["pm"], s["rf"]
    secs.append(
        _Section(
            "Evolution",
            [
                f"RF: {rf['generations']} generations, best fitness {rf['best_fitness']:.2f} "
                f"(branch fitness over {rf['episodes']} crossroad episodes, averaged over the "
                f"genome and {rf['noise']['copies']} copies perturbed by N(0, "
                f"{rf['noise']['sigma']}²); the paper's terms of "
                f"the best: F_M {rf['paper_F_M']:.2f}, F_R {rf['paper_F_R']:.2f}, F_L "
                f"{rf['paper_F_L']:.2f}).",
                f"LF: the 3 connections re-evolved are {', '.join(lf['connections'])} (paper "
                f"notation {', '.join(lf['connections_paper_notation'])}; the paper changed "
                f"W_23, WE_21, WE_22), chosen among {len(s['lf_search']['triples'])} triples; "
                f"best fitness {lf['best_fitness']:.2f} (F_L {lf['paper_F_L']:.2f}).",
                f"IM: programmable {', '.join(im['connections_paper_notation'])}, "
                f"{im['neurons']} neurons; RF program {_vec(im['programs']['right'])}, "
                f"LF program {_vec(im['programs']['left'])}.",
                f"PM: {pm['generations']} generations, reward {pm['best_fitness']:.1f} of at most "
                f"{pm['max_fitness']:.0f} ("
                + (
                    "the paper's two trials: right-rule score with one-colour tiles x left-rule "
                    "score with two-colour tiles"
                    if pm["reward"] == "paper"
                    else "the paper's product, over its two trials plus switching, memory and "
                    "rest episodes: docs/experiments.md"
                )
                + f"), camera range {pm['camera_range']:g} m.",
            ],
            images=[images["de"]],
        )
    )
    secs.append(
        _Section(
            "Trajectories",
            [
                "Each test's paper-protocol trials drawn on the maze (tiles: orange one-colour, "
                "blue/magenta two-colour; shaded cells are junctions)."
            ],
            images=images["trajectories"],
        )
    )
    secs.append(
        _Section(
            "The MBN switching behaviour",
            [
                "One MBN episode recorded every step: what the camera sees, the program the PM "
                "sends, the interpreter's neurons and the motor commands; and the same episode "
                "as an animation."
            ],
            images=[images["traces"], images["gif"]],
        )
    )
    timings = repro.out / "timings.json"
    if timings.exists():
        tm = json.loads(timings.read_text())
        secs.append(
            _Section(
                "Time",
                [
                    "Wall-clock seconds per stage of this run (a resumed run counts only what "
                    "it ran): " + ", ".join(f"{k} {val:g}" for k, val in tm["stages"].items()) + "."
                ],
            )
        )
    return secs


def _yes(ok: bool) -> str:
    return "yes" if ok else "no"


def _vec(v: list[float]) -> str:
    return "(" + ", ".join(f"{x:.3g}" for x in v) + ")"


def _markdown(secs: list[_Section]) -> str:
    lines = ["# mbn reproduce: the Multiple Behavior Network, end to end", ""]
    for sec in secs:
        lines += [f"## {sec.title}", ""]
        for p in sec.text:
            lines += [p, ""]
        if sec.table:
            head, rows = sec.table
            lines.append("| " + " | ".join(head) + " |")
            lines.append("|" + "---|" * len(head))
            for r in rows:
                lines.append("| " + " | ".join(c.replace("|", "\\|") for c in r) + " |")
            lines.append("")
        for file, caption in sec.images:
            lines += [f"![{caption}]({file})", "", f"*{caption}*", ""]
    return "\n".join(lines)


_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,sans-serif;max-width:1100px;margin:2em auto;
padding:0 1em;color:#222;line-height:1.45}
h1{font-size:1.6em}h2{margin-top:1.8em;border-bottom:1px solid #ddd;padding-bottom:.2em}
table{border-collapse:collapse;width:100%;font-size:.9em;margin:1em 0}
th,td{border:1px solid #ccc;padding:.35em .5em;vertical-align:top;text-align:left}
th{background:#f3f3f3}tr.pass td:last-child{background:#d9f2d9;font-weight:600}
tr.fail td:last-child{background:#f8d4d4;font-weight:600}
figure{margin:1em 0}img{max-width:100%;border:1px solid #eee}figcaption{color:#555;font-size:.9em}
code{background:#f5f5f5;padding:0 .2em}
"""


def _inline(text: str) -> str:
    """Escape, then the little markdown the report uses: `code` and **bold** / *italics*."""
    import re

    out = html.escape(text)
    out = re.sub(r"`([^`]+)`", r"<code>\1</code>", out)
    out = re.sub(r"\*\*([^*]+)\*\*", r"<b>\1</b>", out)
    return re.sub(r"\*([^*]+)\*", r"<i>\1</i>", out)


def _html(secs: list[_Section], out: Path) -> str:
    parts = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        "<title>mbn reproduce report</title>",
        f"<style>{_CSS}</style></head><body>",
        "<h1>mbn reproduce: the Multiple Behavior Network, end to end</h1>",
    ]
    for sec in secs:
        parts.append(f"<h2>{html.escape(sec.title)}</h2>")
        parts += [f"<p>{_inline(p)}</p>" for p in sec.text]
        if sec.table:
            head, rows = sec.table
            parts.append("<table><tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in head))
            for k, r in enumerate(rows):
                ok = sec.status[k] if sec.status else None
                cls = "" if ok is None else (" class='pass'" if ok else " class='fail'")
                parts.append(f"<tr{cls}>" + "".join(f"<td>{_inline(c)}</td>" for c in r) + "</tr>")
            parts.append("</table>")
        for file, caption in sec.images:
            data = base64.b64encode((out / file).read_bytes()).decode("ascii")
            mime = "image/gif" if file.endswith(".gif") else "image/png"
            parts.append(
                f"<figure><img src='data:{mime};base64,{data}' alt='{html.escape(caption)}'>"
                f"<figcaption>{html.escape(caption)}</figcaption></figure>"
            )
    parts.append("</body></html>")
    return "\n".join(parts)


def write_report(repro: Any, results: dict[str, Any]) -> None:
    """Figures, ``report.md`` and ``report.html`` of a finished run."""
    from mbn.experiments.reproduce import STAGES
    from mbn.viz.multiplier import plot_multiplier_error

    out = repro.out
    stages = {name: repro.stage(name) for name in STAGES}
    images: dict[str, Any] = {}
    plot_multiplier_error(repro._multiplier_model(), out / "figures" / "multiplier_error.png")
    images["multiplier"] = (
        "figures/multiplier_error.png",
        "The multiplier's absolute and relative error over [0, 1]^2",
    )
    _de_curves(stages, out / "figures" / "de_curves.png")
    images["de"] = ("figures/de_curves.png", "DE: best and mean fitness per generation")
    images["trajectories"] = _trajectories(repro, stages, out)
    spec, maze, traj, b = _mbn_recording(repro)
    _mbn_traces(spec, traj, b, out / "figures" / "mbn_traces.png")
    images["traces"] = (
        "figures/mbn_traces.png",
        "Camera, program, interpreter neurons and motor commands around behaviour switches",
    )
    _mbn_gif(spec, maze, traj, b, out / "figures" / "mbn.gif")
    images["gif"] = ("figures/mbn.gif", "The MBN robot switching behaviour at tiles")
    secs = _sections(repro, results, images)
    with atomic_open(out / "report.md") as handle:
        handle.write(_markdown(secs) + "\n")
    with atomic_open(out / "report.html") as handle:
        handle.write(_html(secs, out) + "\n")
