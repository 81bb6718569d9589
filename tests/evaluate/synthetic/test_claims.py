"""The seed's synthetic claims (``synthetic.claims``): each verdict follows from the numbers it is given, and a
claim the numbers contradict reads "does not hold" (or "partly" where its rule says so), never "holds"."""
from __future__ import annotations

import pytest

from edgetruth.evaluate.synthetic import claims as cl

FIXED = [f"erf{m}_fixed{w}" for m in ("2p", "4p") for w in (5, 7, 9, 11)]


def table(rmse: dict, us: dict | None = None, significant: bool = True, sens_best: float = 0.0,
          shares: dict | None = None) -> dict:
    """A synthetic study's tables as ``claims.check`` reads them, with these RMSEs (px) on every subset."""
    us = us or {}
    rows = [{"method": m, "rmse_common": v, "rmse_all": v, "rmse_refined": v, "us_per_point": us.get(m, 1.0)}
            for m, v in rmse.items()]
    shares = shares or {"ideal": (0.1, 0.1, 0.3, 0.5), "slope": (0.1, 0.2, 0.3, 0.4),
                        "texture": (0.1, 0.2, 0.3, 0.4), "asymmetric": (0.1, 0.4, 0.4, 0.1)}
    windows = [{"model": "4p", "scenario": s, "w5": a, "w7": b, "w9": c, "w11": d}
               for s, (a, b, c, d) in shares.items()]
    wilcoxon = [{"method": m, "significant": significant, "median_difference": 0.01, "p_value": 1e-4}
                for m in cl.SEED_RMSE if m not in ("dynamic_erf_2p", "dynamic_erf_4p")]
    deltas = [-0.10, -0.05, 0.0, 0.05, 0.10]
    sens = [{"delta": d, "rmse_common": 0.16 + (0.0 if d == sens_best else 0.002 + abs(d) / 100),
             "rmse": 0.16, "rel_rmse_change_pct": 100 * d / 10 * (2 if d > 0 else -1)} for d in deltas]
    per = [{"method": m, "texture_rmse_common": v, "asymmetric_rmse_common": v} for m, v in rmse.items()]
    return {"all": rows, "windows": windows, "wilcoxon": wilcoxon, "sensitivity": {"4p": sens}, "per_scenario": per}


def verdicts(t: dict) -> dict:
    return {c["claim"].split(" (")[0].split(":")[0]: c["verdict"] for c in cl.check(t)}


def seed_world() -> dict:
    """The seed's RMSEs, its fixed windows 6 % behind the dynamic ones."""
    rmse = dict(cl.SEED_RMSE)
    rmse.update({f: rmse["dynamic_erf_" + f[3:5]] / 0.94 * (1 + 0.01 * int(f.split("fixed")[1]) / 11) for f in FIXED})
    return rmse


def test_the_seeds_own_numbers_hold_every_claim():
    t = table(seed_world(), us={"dynamic_erf_4p": 1.0, "erf4p_fixed11": 2.0})
    out = cl.check(t)
    assert len(out) == 11 and all(c["evidence"] for c in out)
    assert {c["verdict"] for c in out} == {"holds"}, [(c["claim"], c["verdict"]) for c in out]


def test_a_dynamic_window_that_loses_does_not_hold():
    """Dynamic 4P worse than every method: the lowest-RMSE, better-than-fits, beats-fixed and per-scenario claims
    read "does not hold"; slower than the 11-point fit, the time claim too; baselines not significant, the Wilcoxon
    claim too."""
    rmse = seed_world()
    rmse["dynamic_erf_4p"] = 0.30
    v = verdicts(table(rmse, us={"dynamic_erf_4p": 3.0, "erf4p_fixed11": 2.0}, significant=False))
    for claim in ("ProposedDynamicERF_4P has the lowest overall RMSE of all methods",
                  "Dynamic 4P beats the best fixed window by ~5-6 % RMSE",
                  "Dynamic 4P is 4-8 % better in RMSE than Arctan, Sigmoid, Hagara and PAE",
                  "Dynamic 4P differs significantly",
                  "The dynamic methods cost less time per point than the largest fixed window",
                  "Dynamic 4P has the lowest RMSE in the Texture scenario",
                  "Dynamic 4P has the lowest RMSE in the Asymmetric scenario"):
        matches = [k for k in v if claim.startswith(k) or k.startswith(claim)]
        assert matches and all(v[k] == "does not hold" for k in matches), (claim, v)


@pytest.mark.parametrize("gain, verdict", [(0.06, "holds"), (0.02, "partly"), (-0.02, "does not hold")])
def test_beating_the_fixed_windows_by_less_than_4_percent_is_partly(gain, verdict):
    rmse = seed_world()
    for f in FIXED:
        if f.startswith("erf4p"):
            rmse[f] = rmse["dynamic_erf_4p"] / (1 - gain)
    assert verdicts(table(rmse))["Dynamic 4P beats the best fixed window by ~5-6 % RMSE"] == verdict


def test_window_shares_and_threshold_sensitivity_follow_their_rules():
    """Shares that meet none of the three criteria: "does not hold"; the lowest RMSE off δ = 0 breaks one part of
    the sensitivity claim: "partly"."""
    none = {s: (0.7, 0.1, 0.1, 0.1) for s in ("ideal", "slope", "texture")} | {"asymmetric": (0.1, 0.1, 0.1, 0.7)}
    v = verdicts(table(seed_world(), shares=none, sens_best=0.05))
    assert v["Window shares"] == "does not hold" and v["Threshold sensitivity"] == "partly"
