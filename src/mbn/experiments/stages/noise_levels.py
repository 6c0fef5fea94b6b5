"""Stage ``noise_levels``: what survives noise. Each channel of the noise model
(:class:`mbn.world.sensors.NoiseConfig`, ``docs/noise.md``) is swept alone over its levels, and
all of them together at a "realistic" level, for RF, the interpreter with RF's and LF's programs
and the MBN, on the jittered test maze and the held-out one: success with a Wilson 95 % interval
at every level. Each (channel, level) draws its noise from the stage's key folded with both."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import jax

from mbn.config import Settings, setting
from mbn.controllers import make_controller, read_controller_spec
from mbn.experiments.pipeline import Stage, StageContext
from mbn.experiments.pipeline.results import Record
from mbn.experiments.stages.common import run_noise
from mbn.experiments.stages.keys import KEYS
from mbn.experiments.stages.protocol import TESTED, test_specs
from mbn.experiments.stages.records import RateRecord, TrialCounts
from mbn.experiments.stages.tests import TestsSettings
from mbn.experiments.trials import TrialGroup, rate_record, run_trial_groups
from mbn.world.mazes.load import load_maze
from mbn.world.sensors import NoiseConfig

__all__ = [
    "CHANNELS",
    "CONTROLLERS",
    "REALISTIC",
    "LevelPoint",
    "NoiseLevelsResult",
    "NoiseLevelsSettings",
    "NoiseLevelsStage",
]

_DOC = "docs/noise.md"

#: The channels swept, each a key of :class:`NoiseConfig`.
CHANNELS = (
    "sonar_std",
    "sonar_dropout",
    "camera_miss",
    "camera_false",
    "wheel_std",
    "neuron_std",
    "program_std",
    "corridor_scale",
    "sonar_cone",
    "wheel_bias",
)

#: The controllers tested, in batches that share a controller function: name -> (file, program).
CONTROLLERS = {"rf": ("rf", None), "im_rf": ("im", "right"), "im_lf": ("im", "left")} | {
    "mbn": ("mbn", None)
}
_BATCHES = (("rf",), ("im_rf", "im_lf"), ("mbn",))

#: The "realistic" level of every channel at once (issue: sonar 2 cm, dropout 1 %, wheels 5 %,
#: camera misses 5 %).
REALISTIC = NoiseConfig(sonar_std=0.02, sonar_dropout=0.01, wheel_std=0.05, camera_miss=0.05)


def _uses(name: str, channel: str) -> bool:
    """Whether a controller reads the channel (no camera but the MBN's, no program lines in a
    plain network)."""
    if channel.startswith("camera"):
        return name == "mbn"
    if channel == "program_std":
        return name != "rf"
    return True


def _levels(default: tuple[float, ...], doc: str, unit: str = "") -> Any:
    return setting(default, doc=doc, unit=unit, low=0.0, high=100.0, source=_DOC)


@dataclass(frozen=True)
class NoiseLevelsSettings(Settings):
    """The channels swept, the levels of each (the first none), and the trials per level."""

    section = "noise_levels"
    channels: tuple[str, ...] = setting(
        CHANNELS, doc="the channels swept", choices=CHANNELS, source=_DOC
    )
    sonar_std: tuple[float, ...] = _levels(
        (0.0, 0.05, 0.2, 0.5, 1.0, 2.0), "levels of sonar_std", "m"
    )
    sonar_dropout: tuple[float, ...] = _levels(
        (0.0, 0.01, 0.05, 0.1, 0.2, 0.4), "levels of sonar_dropout"
    )
    camera_miss: tuple[float, ...] = _levels(
        (0.0, 0.05, 0.1, 0.2, 0.4, 0.8), "levels of camera_miss"
    )
    camera_false: tuple[float, ...] = _levels(
        (0.0, 0.01, 0.02, 0.05, 0.1, 0.2), "levels of camera_false"
    )
    wheel_std: tuple[float, ...] = _levels((0.0, 0.1, 0.2, 0.5, 1.0, 2.0), "levels of wheel_std")
    neuron_std: tuple[float, ...] = _levels((0.0, 0.1, 0.3, 1.0, 3.0, 10.0), "levels of neuron_std")
    program_std: tuple[float, ...] = _levels(
        (0.0, 0.01, 0.05, 0.1, 0.2, 0.5), "levels of program_std"
    )
    corridor_scale: tuple[float, ...] = _levels(
        (0.0, 0.02, 0.05, 0.1, 0.2, 0.3),
        "levels of corridor_scale (Jakobi: the corridors' width, 0.1 = ±10 %)",
    )
    sonar_cone: tuple[float, ...] = _levels(
        (0.0, 5.0, 10.0, 15.0, 30.0, 60.0), "levels of sonar_cone (Jakobi: the beam)", "degrees"
    )
    wheel_bias: tuple[float, ...] = _levels(
        (0.0, 0.01, 0.02, 0.05, 0.1, 0.2), "levels of wheel_bias (Jakobi: the wheels' bias)"
    )
    jitter_per_mark: int = setting(
        20, doc="jittered trials per start mark of the test maze", low=1, high=1000, source=_DOC
    )
    heldout_repeats: int = setting(
        17, doc="trials per start mark of the held-out maze", low=1, high=1000, source=_DOC
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        from mbn.errors import MbnInputError

        for channel in CHANNELS:
            levels = getattr(self, channel)
            if not levels or levels[0] != 0.0 or list(levels) != sorted(set(levels)):
                raise MbnInputError(
                    f"noise_levels.{channel}: levels must start at 0 and increase, got "
                    f"{list(levels)}"
                )
            NoiseConfig(**{channel: levels[-1]})  # within the channel's range


@dataclass(frozen=True, kw_only=True)
class LevelPoint(Record):
    """A controller at one noise level: its jittered and held-out trials."""

    level: float
    jitter: RateRecord
    heldout: RateRecord


@dataclass(frozen=True, kw_only=True)
class NoiseLevelsResult(Record):
    """What the ``noise_levels`` stage records (``stages/noise_levels.json``): the channels and
    their levels, each controller's success curve over them, the realistic noise's results,
    the trials per level, and the noise the controllers were evolved under."""

    channels: list[str]
    levels: dict[str, list[float]]
    curves: dict[str, dict[str, list[LevelPoint]]]
    realistic: dict[str, Any]
    trials: TrialCounts
    evolved_under: dict[str, Any]

    #: The key of the realistic noise's levels among its controllers' points.
    REALISTIC_NOISE: ClassVar[str] = "noise"

    def realistic_point(self, controller: str) -> LevelPoint:
        """A controller's trials under the realistic noise."""
        return LevelPoint.from_json(
            self.realistic[controller], f"noise_levels: realistic.{controller}"
        )

    @property
    def realistic_noise(self) -> dict[str, float]:
        """The realistic noise's levels, by channel."""
        return dict(self.realistic[self.REALISTIC_NOISE])


class NoiseLevelsStage(Stage[NoiseLevelsResult]):
    name = "noise_levels"
    key_id = KEYS["noise_levels"]
    needs = ("rf", "im", "pm")
    settings = NoiseLevelsSettings

    result = NoiseLevelsResult

    def run(self, ctx: StageContext) -> NoiseLevelsResult:
        s: NoiseLevelsSettings = ctx.settings
        tests = ctx.section(TestsSettings)
        mazes = [load_maze(tests.maze), load_maze(tests.heldout_maze)]
        specs = {
            name: read_controller_spec(ctx.rundir.controller_file(file))
            for name, (file, _) in CONTROLLERS.items()
        }
        rules = dict(TESTED)
        points: list[tuple[str, int, NoiseConfig]] = [("none", 0, NoiseConfig())]
        for channel in s.channels:
            for i, level in enumerate(getattr(s, channel)[1:], start=1):
                points.append((channel, i, NoiseConfig(**{channel: level})))
        points.append(("realistic", 1, REALISTIC))
        out: dict[str, Any] = {name: {} for name in CONTROLLERS}
        bar = ctx.progress.task("noise levels", len(points))
        for p, (channel, i, noise) in enumerate(points):
            key = jax.random.fold_in(jax.random.fold_in(ctx.key, p), i)
            ctx.progress.update(bar, completed=p, info=f"{channel} {i}")
            for batch in _BATCHES:
                names = [n for n in batch if channel in ("none", "realistic") or _uses(n, channel)]
                if not names:
                    continue
                loaded = {
                    n: make_controller(specs[n], CONTROLLERS[n][1], where=n, noise=noise)
                    for n in names
                }
                first = loaded[names[0]]
                groups = []
                for n in names:
                    seconds = tests.mbn_seconds if n == "mbn" else tests.seconds
                    ran = test_specs(
                        rules[n],
                        seconds=seconds,
                        jitter_per_mark=s.jitter_per_mark,
                        heldout_repeats=s.heldout_repeats,
                        test_seed=ctx.seeds["test_jitter"],
                        heldout_seed=ctx.seeds["heldout_jitter"],
                        initial=loaded[n].initial_rule,
                    )
                    groups += [
                        TrialGroup(
                            f"{n}{x}", 1 if x == "_heldout" else 0, ran[x], loaded[n].initial_state
                        )
                        for x in ("_jitter", "_heldout")
                    ]
                verdicts, _, _, _ = run_trial_groups(
                    mazes,
                    groups,
                    first.controller,
                    seconds=max(g.spec.seconds for g in groups),
                    dt=first.dt,
                    sensors=first.sensors,
                    camera=first.camera,
                    noise=noise,
                    key=key if noise.enabled else None,
                    until_judged=True,
                )
                for n in names:
                    entry = out[n].setdefault(channel, [])
                    level = 0.0 if channel in ("none", "realistic") else getattr(noise, channel)
                    entry.append(
                        {
                            "level": level,
                            "jitter": rate_record(verdicts[f"{n}_jitter"]),
                            "heldout": rate_record(verdicts[f"{n}_heldout"]),
                        }
                    )
            ctx.progress.update(bar, completed=p + 1, info=f"{channel} {i}")
        curves: dict[str, Any] = {}
        for n in CONTROLLERS:
            base = out[n]["none"][0]
            curves[n] = {
                channel: [base, *out[n][channel]] if channel in out[n] else []
                for channel in s.channels
            }
            curves[n] = {c: v for c, v in curves[n].items() if v}
        return NoiseLevelsResult.from_json(
            {
                "channels": list(s.channels),
                "levels": {c: list(getattr(s, c)) for c in s.channels},
                "curves": curves,
                "realistic": {
                    NoiseLevelsResult.REALISTIC_NOISE: REALISTIC.as_dict(),
                    **{n: out[n]["realistic"][0] for n in CONTROLLERS},
                },
                "trials": {
                    "jitter_per_mark": s.jitter_per_mark,
                    "heldout_repeats": s.heldout_repeats,
                },
                # the noise the controllers were evolved, validated and tested under ([noise])
                "evolved_under": {k: v for k, v in run_noise(ctx).as_dict().items() if v},
            }
        )

    def summary(self, result: NoiseLevelsResult) -> str:
        return "realistic noise: " + ", ".join(
            f"{n} {result.realistic_point(n).jitter.rate:.0%}" for n in CONTROLLERS
        )
