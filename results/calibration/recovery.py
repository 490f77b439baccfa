"""Proof on known truth (issue 31): the calibration experiments run in comat with the reality
layer at random known settings (kinematic robots, as the Robotarium simulator moves them, so the
logs show the layer and nothing else), fitted by `comat calibrate`'s fit; and the same
experiments under the Robotarium simulator (PyPI `rps`), where the fit must find no gap.

    python results/calibration/recovery.py > results/calibration/recovery.md

Tolerances (:func:`comat.calibration.recovery.check`; tests/test_calibration.py checks two settings and rps): the total
delay (pose + command) exactly for the median robot and the profile's minimum, from ``steps`` and
from ``spin``; the lag τ, the pose noise (x, y and θ) and the hold probability within 20 %; the dead
zone within 0.4 rad/s (median robot; the lag reads as up to ~0.35 rad/s); each robot's half gain
difference (g_r − g_l)/2 from ``spin`` within 0.01 of the layer's own draw (about two standard
errors at 3 mm of pose noise; the layer's spreads reach 0.05).

A second table fits the same experiments run in comat's MuJoCo tiers at reality ``off``: what the
tiers' own actuators add to the layer (the tier's servo lag, gain, slew). A third runs the six
settings in both tiers: the fit then sees the layer and the tier's own actuator together, so its
tolerance is the delay exact (median robot) from ``spin`` or ``steps``, τ between the layer's τ and
the layer's plus the tier's own (each ± 20 %), noise and holds within 20 %. A fourth fits the
experiments with every nuisance of `nominal` on, twelve seeds, against NOMINAL_TOLERANCES (the table
in docs/calibration.md).
"""

import tempfile
import warnings
from pathlib import Path

import numpy as np

from comat.calibration.experiments import run_under_rps, simulate
from comat.calibration.fit import fit_ramp, fit_spin, fit_steps, fit_still
from comat.calibration.recovery import NOMINAL_TOLERANCES, check, check_level, recover, recover_level, setting

warnings.simplefilter("ignore")  # rps's own warnings


def main() -> None:
    rng = np.random.default_rng(2026)
    print(
        "| setting | delay (ticks) truth → fit: steps, spin | τ (s) truth → fit | noise x,y (mm) truth → fit | "
        "noise θ (rad) truth → fit | hold truth → fit | dead zone (rad/s) truth → fit | gain spread: largest "
        "error of (g_r − g_l)/2 | within tolerance |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for k in range(6):
        t = setting(rng)
        g = recover(t, seed=k)
        ok = check(t, g)
        total = t["pose_delay_ticks"] + t["command_delay_ticks"]
        print(
            f"| {k} | {total} ({t['pose_delay_ticks']}+{t['command_delay_ticks']}) → {g['delay_median']}, "
            f"{g['spin_delay_median']} | {t['motor_tau_min_s']:.3f} → {g['tau']:.4f} | {1e3 * t['pose_noise_xy_m']:.2f} → "
            f"{1e3 * g['noise_xy']:.2f} | {t['pose_noise_theta_rad']:.3f} → {g['noise_theta']:.4f} | "
            f"{t['pose_hold_prob']:.2f} → {g['hold']:.3f} | {t['motor_dead_zone_radps']:.1f} → {g['dead_zone']:.2f} | "
            f"{t['wheel_gain_spread']:.3f}: {g['gain_diff_error']:.4f} | "
            f"{'all' if all(ok.values()) else 'not: ' + ', '.join(k for k, v in ok.items() if not v)} |"
        )
    steps, still = fit_steps(run_under_rps("steps")), fit_still(run_under_rps("still"))
    spin, ramp = fit_spin(run_under_rps("spin")), fit_ramp(run_under_rps("ramp"))
    moving = steps + spin
    print(
        f"| rps (no gap) | 0 → {max(r['delay_ticks'] for r in moving)} (max over robots, both) | 0 → "
        f"{max(r['tau_own_s'] for r in moving):.4f} | 0 → {1e3 * max(r['noise_xy_m'] for r in still):.2f} | 0 → "
        f"{max(r['noise_theta_rad'] for r in still):.4f} | not identified (poses never change) | 0 → "
        f"{max(r['dead_zone_radps'] for r in ramp):.2f} | 0: {max(abs(r['half_gain_diff']) for r in moving):.1e} | "
        f"speed gain {min(r['gain'] for r in steps):.3f}–{max(r['gain'] for r in steps):.3f}, turn gain "
        f"{min(r['gain'] for r in spin):.3f}–{max(r['gain'] for r in spin):.3f}; no cap below the fastest commanded |"
    )
    print()
    print("What comat's MuJoCo tiers add at reality `off` (the same experiments, four robots; all robots alike):")
    print()
    print(
        "| tier | delay (ticks) | τ (s) | speed gain | turn gain | slew (rad/s²) | reachable / commanded full | "
        "(g_r − g_l)/2 | dead zone (rad/s) |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    own_tau = {}
    for tier in ("unicycle", "wheels"):
        st = fit_steps(simulate("steps", "off", n=4, seed=0, tier=tier))
        sp = fit_spin(simulate("spin", "off", n=4, seed=0, tier=tier))
        ra = fit_ramp(simulate("ramp", "off", n=4, seed=0, tier=tier))
        a, b = st[0], sp[0]
        own_tau[tier] = a["tau_s"]
        print(
            f"| {tier} | {a['delay_ticks']}, {b['delay_ticks']} | {a['tau_s']:.4f}, {b['tau_s']:.4f} | {a['gain']:.3f} | "
            f"{b['gain']:.3f} | {a['accel_radps2']:.0f} | {a['reach_fraction'] / a['full_fraction']:.2f}, "
            f"{b['reach_fraction'] / b['full_fraction']:.2f} | {max(abs(r['half_gain_diff']) for r in st + sp):.1e} | "
            f"{np.median([r['dead_zone_radps'] for r in ra]):.2f} |"
        )

    tiers_table(own_tau)
    nominal_table()


def tiers_table(own_tau: dict) -> None:
    """The six settings again, in both MuJoCo tiers (the layer on top of the tier's own actuator)."""
    rng = np.random.default_rng(2026)
    print()
    print("The six settings in comat's MuJoCo tiers (the layer plus the tier's own actuator):")
    print()
    print(
        "| setting | tier | delay truth → steps, spin (median robot) | τ layer (+ tier's own) → steps, spin | "
        "noise x,y (mm) truth → fit | hold truth → fit | within tolerance |"
    )
    print("|---|---|---|---|---|---|---|")
    for k in range(6):
        t = setting(rng)
        total, tau = t["pose_delay_ticks"] + t["command_delay_ticks"], t["motor_tau_min_s"]
        for tier in ("unicycle", "wheels"):
            st = fit_steps(simulate("steps", t, n=4, seed=k, tier=tier))
            sp = fit_spin(simulate("spin", t, n=4, seed=k, tier=tier))
            sl = fit_still(simulate("still", t, n=4, seed=k, tier=tier))
            d = [int(np.median([r["delay_ticks"] for r in f])) for f in (st, sp)]
            taus = [st[0]["tau_s"], sp[0]["tau_s"]]
            noise, hold = np.mean([r["noise_xy_m"] for r in sl]), np.mean([r["repeat_share"] for r in sl])
            ok = {
                "delay": total in d,
                "tau": any(0.8 * tau <= x <= 1.2 * (tau + own_tau[tier]) for x, dd in zip(taus, d) if dd == total),
                "noise": abs(noise - t["pose_noise_xy_m"]) <= 0.2 * t["pose_noise_xy_m"],
                "hold": abs(hold - t["pose_hold_prob"]) <= 0.2 * t["pose_hold_prob"],
            }
            print(
                f"| {k} | {tier} | {total} → {d[0]}, {d[1]} | {tau:.3f} (+{own_tau[tier]:.4f}) → {taus[0]:.4f}, "
                f"{taus[1]:.4f} | {1e3 * t['pose_noise_xy_m']:.2f} → {1e3 * noise:.2f} | {t['pose_hold_prob']:.2f} → "
                f"{hold:.3f} | {'all' if all(ok.values()) else 'not: ' + ', '.join(n for n, v in ok.items() if not v)} |"
            )


def nominal_table(seeds: int = 12) -> None:
    """Every nuisance of ``nominal`` on, twelve seeds (four robots each), fitted as ``comat calibrate``
    fits them; each cell is truth → fit, checked against NOMINAL_TOLERANCES."""
    print()
    print(
        "With every nuisance of `nominal` on (per-robot delays with jitter, per-wheel lags, the wheels' disturbance, "
        "command loss, freezes, bias), the four experiments fitted as `comat calibrate` fits them, twelve seeds:"
    )
    print()
    names = list(NOMINAL_TOLERANCES)
    print("| seed | " + " | ".join(f"`{n}`" for n in names) + " | within tolerance |")
    print("|---" * (len(names) + 2) + "|")
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(seeds):
            got = check_level(recover_level("nominal", seed, Path(tmp)))
            cells = [got[n][1] + ("" if got[n][0] else " **(out)**") for n in names]
            bad = [n for n in names if not got[n][0]]
            print(f"| {seed} | " + " | ".join(cells) + f" | {'all' if not bad else 'not: ' + ', '.join(bad)} |")


if __name__ == "__main__":
    main()
