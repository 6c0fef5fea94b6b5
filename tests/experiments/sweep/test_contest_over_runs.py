"""Programs against dynamics over runs (``mbn.experiments.contest.over_runs``), from
``results.json`` files as the experiment writes them: k of N with Wilson intervals, censored
medians, the median run, the comparisons, the report's sections and the solved-curve figure;
and the sweep's view of the experiment (no per-run targets)."""

from __future__ import annotations

import json

import pytest

from mbn.experiments.contest.over_runs import contest_over_runs, seed_table, statistics
from mbn.experiments.contest.sweep import CONTEST_SPEC
from mbn.experiments.sweep.report import summary_line
from mbn.experiments.sweep.specs import sweep_spec
from mbn.stats import mann_whitney, median_ratio, wilson_interval

BUDGET = 5418


def _results(times: dict[str, int | None], final: dict[str, bool] | None = None):
    final = final or {}
    return {
        "contest": {
            "straight-right": {
                who: {
                    "solved": t is not None,
                    "evaluations": t,
                    "budget": BUDGET,
                    "final_success": final.get(who, t is not None),
                    "genes": 14 if who == "programs" else 12,
                }
                for who, t in times.items()
            }
        },
        "tests": {},
    }


RUNS = {
    0: _results({"programs": 180, "scratch": None, "neighbour": 900}),
    1: _results({"programs": 360, "scratch": 2000, "neighbour": None}),
    2: _results({"programs": None, "scratch": None, "neighbour": 540}, {"programs": False}),
    3: _results({"programs": 540, "scratch": 4000, "neighbour": 720}),
    4: _results({"programs": 720, "scratch": None, "neighbour": 1800}, {"neighbour": False}),
}


def test_statistics_count_runs_and_censor_the_unsolved():
    s = statistics(RUNS)["rules"]["straight-right"]
    assert s["budget"] == BUDGET
    p, sc, nb = (s["contenders"][w] for w in ("programs", "scratch", "neighbour"))
    assert (p["solved"], sc["solved"], nb["solved"]) == (4, 2, 4)
    assert p["solved_wilson95"] == pytest.approx(wilson_interval(4, 5))
    assert nb["final_success"] == 3  # seed 4's last best no longer passes
    # programs: 180, 360, 540, 720, censored: median 540; scratch: 2000, 4000, 3 censored
    assert p["median"] == 540 and p["q1"] == 360 and p["q3"] == 720
    assert sc["median"] is None and sc["median_censored"] is True
    assert p["median_run"] == {
        "seed": 3,
        "evaluations": 540,
        "controller": "seed-3/controllers/contest_straight-right_programs.json",
    }
    times = {
        w: [RUNS[k]["contest"]["straight-right"][w]["evaluations"] for k in RUNS]
        for w in s["contenders"]
    }
    vs = s["versus"]["neighbour"]
    u = mann_whitney(times["programs"], times["neighbour"], BUDGET)
    assert {k: v for k, v in vs["mann_whitney"].items() if k != "p_holm"} == u
    # Holm across the rule's two comparisons: the smaller p doubled, the larger at least it
    ps = {who: s["versus"][who]["mann_whitney"]["p"] for who in ("scratch", "neighbour")}
    low, high = sorted(ps, key=lambda w: ps[w])
    assert s["versus"][low]["mann_whitney"]["p_holm"] == pytest.approx(min(1, 2 * ps[low]))
    assert s["versus"][high]["mann_whitney"]["p_holm"] == pytest.approx(
        max(min(1, 2 * ps[low]), ps[high])
    )
    # programs needs fewer evaluations than neighbour in most pairs of runs
    poi = vs["improvement"]
    assert 0.5 < poi["p"] <= 1 and poi["low"] <= poi["p"] <= poi["high"]
    assert poi["p"] == pytest.approx(1 - u["A12"], abs=1e-12)  # the same pairs, seen from b
    assert vs["ratio"] == median_ratio(times["programs"], times["neighbour"], BUDGET, seed=0)
    assert vs["ratio"]["ratio"] == pytest.approx(540 / 900)
    # scratch's median is censored: programs' ratio to it is 0
    assert s["versus"]["scratch"]["ratio"]["ratio"] == 0.0
    assert set(s["versus"]) == {"scratch", "neighbour"}
    curve = p["curve"]
    assert curve["solved"][0] == 0.0 and curve["solved"][-1] == pytest.approx(0.8)


def test_the_report_sections_and_the_figure(tmp_path):
    stats, secs, images = contest_over_runs(tmp_path, RUNS)
    assert stats == statistics(RUNS)
    titles = [s.title for s in secs]
    assert titles == [
        "Programs against dynamics: straight-right",
        "Program search against each dynamics contender: straight-right",
        "The 2016 claim over runs",
        "Evaluations to success, seed by seed",
    ]
    header, rows = secs[0].table
    assert "median run" in header
    # runs recorded before [contest] program_checks checked programs as networks; the report
    # says how the checks of the runs it pools ran
    assert stats["program_checks"] == ["network"]
    assert "ran on the network the program encodes" in secs[0].text[0]
    mixed = {**RUNS, 99: {**RUNS[next(iter(RUNS))], "program_checks": "interpreter"}}
    assert statistics(mixed)["program_checks"] == ["interpreter", "network"]
    _, secs2, _ = contest_over_runs(
        tmp_path, {k: {**r, "program_checks": "interpreter"} for k, r in RUNS.items()}
    )
    assert "ran through the fixed interpreter" in secs2[0].text[0]
    assert [r[0] for r in rows] == ["programs", "scratch", "neighbour"]
    assert rows[0][1].startswith("4 of 5") and rows[1][2].startswith("> budget")
    assert [r[0] for r in secs[1].table[1]] == ["programs : scratch", "programs : neighbour"]
    ((file, _),) = images
    assert (tmp_path / file).stat().st_size > 0


def test_the_seed_by_seed_table_gives_every_run_of_every_contender():
    runs = {**RUNS, 7: {"contest": {}, "tests": {}}}  # a run without the contest: no row
    runs[5] = _results({"programs": 900})  # a run with program search only
    header, rows = seed_table(statistics(runs))
    assert header == [
        "seed",
        "straight-right: programs",
        "straight-right: scratch",
        "straight-right: neighbour",
    ]
    assert rows == [
        ["0", "180", "> budget", "900"],
        ["1", "360", "2000", "> budget"],
        ["2", "> budget", "> budget", "540"],
        ["3", "540", "4000", "720"],
        ["4", "720", "> budget", "1800"],
        ["5", "900", "–", "–"],
    ]
    assert seed_table(statistics({})) is None


def test_the_sweep_runs_it_without_per_run_targets():
    assert sweep_spec("programs-vs-dynamics") is CONTEST_SPEC
    assert CONTEST_SPEC.targets == () and CONTEST_SPEC.analysis is not None
    assert "programs_straight_right_jitter" in CONTEST_SPEC.tests
    assert "im_programs_straight_left_heldout" in CONTEST_SPEC.tests
    data = {
        "summary": {
            "seeds": [0, 1],
            "finished": 2,
            "failed": [],
            "meet_every_target": 2,
            "per_seed": {"0": {"state": "done"}, "1": {"state": "done"}},
            "tests": {},
            "targets": {},
            "claims": [],
            "analysis": {},
        },
        "runs": {},
    }
    assert summary_line(data) == "sweep: 2/2 seeds finished (no per-run targets)"


def _im_tests(marks: tuple[int, int], jitter: tuple[int, int]) -> dict:
    short = "straight_right"
    return {
        f"im_programs_{short}": {"successes": marks[0], "trials": marks[1]},
        f"im_programs_{short}_jitter": {
            "successes": jitter[0],
            "trials": jitter[1],
            "success_rate": jitter[0] / jitter[1],
        },
    }


def test_program_search_counts_the_programs_that_pass_through_the_interpreter(tmp_path):
    runs = {k: {**r, "config": {"contest": {"jitter_target": 0.95}}} for k, r in RUNS.items()}
    given = [((11, 11), (220, 220)), ((10, 11), (220, 220)), ((11, 11), (209, 220))]
    given += [((11, 11), (208, 220)), ((11, 11), (185, 220))]
    for k, (m, j) in zip(runs, given, strict=True):
        runs[k] = {**runs[k], "tests": _im_tests(m, j)}
    c = statistics(runs)["rules"]["straight-right"]["contenders"]
    # seed 0 passes; seed 1 fails a mark; seed 2 at 95.0 % passes; 94.5 % and 84 % do not
    assert c["programs"]["interpreter_success"] == 2
    assert c["programs"]["interpreter_wilson95"] == pytest.approx(wilson_interval(2, 5))
    assert "interpreter_success" not in c["scratch"]
    _, secs, _ = contest_over_runs(tmp_path, runs)
    header, rows = secs[0].table
    col = header.index("through the interpreter")
    assert rows[0][col].startswith("2 of 5") and rows[1][col] == "–"
    # runs without the interpreter's tests (older results): no count, no claim
    assert (
        "interpreter_success"
        not in statistics(RUNS)["rules"]["straight-right"]["contenders"]["programs"]
    )


def _runs_of(n: int, programs: int | None, other: int | None) -> dict[int, dict]:
    return {
        k: _results({"programs": programs + k, "scratch": other, "neighbour": other})
        if programs is not None
        else _results({"programs": None, "scratch": other + k, "neighbour": other + k})
        for k in range(n)
    }


def test_the_2016_claim_is_judged_over_20_runs_whichever_way_it_falls():
    # program search always faster (others never solve): holds
    fast = statistics(_runs_of(20, 180, None))["claim"]
    assert fast["pass"] is True and "faster" in fast["measured"]
    # program search never solves, the others do: fails, and says so
    slow = statistics(_runs_of(20, None, 900))["claim"]
    assert slow["pass"] is False and "slower" in slow["measured"]
    # no difference (the same evaluations): fails as not 'faster'
    same = {k: _results({"programs": 900, "scratch": 900, "neighbour": 900}) for k in range(20)}
    tie = statistics(same)["claim"]
    assert tie["pass"] is False and "no clear difference" in tie["measured"]
    # fewer than 20 runs: figures given, no verdict
    few = statistics(_runs_of(8, 180, None))["claim"]
    assert few["pass"] is None and few["measured"].startswith("preliminary, 8 runs")


def test_a_claim_no_run_judges_is_not_counted_as_failing(tmp_path):
    from mbn.experiments.sweep.summary import summarize

    runs = {
        k: {**r, "claims": [{"claim": "c", "pass": None, "target": "t"}]} for k, r in RUNS.items()
    }
    s = summarize(runs, {}, CONTEST_SPEC)
    assert s["claims"] == [{"claim": "c", "runs": 5, "hold": 0, "judged": 0, "criterion": "t"}]


def test_a_contest_sweep_folder_is_summarized_into_its_report(tmp_path):
    """``mbn sweep --summarize`` on a programs-vs-dynamics folder: the per-seed rates drawn (an
    experiment without agreement targets), the contest's sections and its claim over runs."""
    from mbn.experiments.contest import PROGRAMS_VS_DYNAMICS
    from mbn.experiments.sweep.report import summarize_folder
    from mbn.experiments.sweep.run import seed_dir

    from .conftest import fake_sweep

    config = PROGRAMS_VS_DYNAMICS.config(quick=True).to_dict()
    for seed, r in RUNS.items():
        folder = seed_dir(tmp_path, seed)
        (folder / "stages").mkdir(parents=True)
        tests = {
            name: {"trials": 20, "successes": 19, "success_rate": 0.95}
            for name in CONTEST_SPEC.tests
        }
        claim = {"claim": "learning programs ...", "measured": "", "target": "t", "pass": None}
        results = {**r, "seed": seed, "config": config, "tests": tests, "claims": [claim]}
        (folder / "run.json").write_text(json.dumps({"seed": seed, "config": config}))
        (folder / "results.json").write_text(json.dumps(results))
        (folder / "report.html").write_text("<html></html>")
        curve = [float(g + seed) for g in range(5)]
        (folder / "stages" / "rf.json").write_text(
            json.dumps({"history": {"best": curve, "mean": curve}})
        )
    fake_sweep(tmp_path, list(RUNS), config)
    sweep = json.loads((tmp_path / "sweep.json").read_text())
    sweep["settings"]["experiment"] = "programs-vs-dynamics"
    (tmp_path / "sweep.json").write_text(json.dumps(sweep))
    data = summarize_folder(tmp_path)
    assert data["summary"]["finished"] == 5
    assert data["summary"]["analysis"]["claim"]["pass"] is None  # 5 runs: not judged
    md = (tmp_path / "sweep.md").read_text()
    assert "The 2016 claim over runs" in md and "preliminary, 5 runs" in md
    assert "not judged per run (5 runs)" in md
    # the seeds table has no "meets every target" column: these runs have no per-run target
    seeds_table = md.split("## Seeds", 1)[1].split("##", 1)[0]
    assert "| seed | run | error | time |" in seeds_table
    assert "meets every target" not in seeds_table and "| yes |" not in seeds_table
    assert seeds_table.count("| done | – |") == 5
    for figure in ("sweep_rates.png", "sweep_de.png", "contest_solved.png"):
        assert (tmp_path / "figures" / figure).stat().st_size > 0


def _versus(p, p_holm=None, a12=0.2, ratio=(0.2, 0.1, 0.5)):
    u = {"p": p, "A12": a12}
    if p_holm is not None:
        u["p_holm"] = p_holm
    return {"mann_whitney": u, "ratio": dict(zip(("ratio", "low", "high"), ratio, strict=True))}


def test_the_verdict_reads_the_holm_adjusted_p_where_it_is_recorded():
    from mbn.experiments.contest.over_runs import comparison_verdict

    assert comparison_verdict(_versus(0.03)) == "faster"  # a record without p_holm
    assert comparison_verdict(_versus(0.03, p_holm=0.03)) == "faster"
    assert comparison_verdict(_versus(0.03, p_holm=0.06)) == "no clear difference"
    assert comparison_verdict(_versus(0.01, 0.02, a12=0.8, ratio=(3, 2, 5))) == "slower"


def test_program_search_over_k_connections_is_compared_but_not_part_of_the_2016_claim():
    from mbn.experiments.contest.over_runs import MIN_RUNS, claim_over_runs

    contenders = {w: {"runs": MIN_RUNS} for w in ("programs", "scratch", "programs_k")}
    stats = {
        "rules": {
            "straight-right": {
                "contenders": contenders,
                # faster than the dynamics contender; no faster than programs over k
                "versus": {"scratch": _versus(0.001, 0.002), "programs_k": _versus(0.5, 0.5)},
            }
        }
    }
    claim = claim_over_runs(stats)
    assert claim["pass"] is True
    assert "programs_k" not in claim["measured"] and "p (Holm) 0.002" in claim["measured"]
    assert "Holm-adjusted" in claim["target"]
