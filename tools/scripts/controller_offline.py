"""Replay α* controllers offline on recorded D0 and S (tools/scripts/one_step_energy_record.py).

Usage: python tools/scripts/controller_offline.py RECORD.npy NOISE TOLERANCE

Linear model of one α-RATTLE-4 step n: H − E_ref after it is e_n = e_{n−1} + D0_n + α_n S_n,
with the D0_n and S_n recorded along the triple-jump trajectory (a trial's energy gets
Gaussian noise of std NOISE kJ/mol). Printed:

1. open loop: how well D0 and S of the next step are predicted from their *exact*
   past (last value, linear extrapolation, AR(4) fitted by least squares over the last
   60 steps), and RMS(e) of a one-trial-per-step controller given that exact past;
2. the best fixed α of the linear model;
3. closed loop: a controller that sees only what a step measures — the residual of
   each trial; S only from the secant of a step with two trials (else the prediction
   stands in for it) — one trial at the AR(4) prediction of α*, a second one (two more
   force evaluations) when |r| > threshold. Force evaluations: 4 for one trial, 6 for two.
"""

import sys

import numpy as np


def main() -> None:
    record = np.load(sys.argv[1])
    noise, tolerance = float(sys.argv[2]), float(sys.argv[3])
    d0, slope = record[:, 1], record[:, 2]
    n = len(d0)
    rng = np.random.default_rng(3)

    def rms(x):
        return float(np.sqrt(np.mean(np.square(x))))

    def last(x):
        return x[-1] if len(x) else 0.0

    def linear(x):
        return 2 * x[-1] - x[-2] if len(x) > 1 else last(x)

    def ar4(x, order=4, window=60):
        x = np.asarray(x)
        if len(x) < window + order:
            return last(x)
        lagged = np.array([x[j - order : j][::-1] for j in range(len(x) - window, len(x))])
        gram = lagged.T @ lagged
        coefficients = np.linalg.solve(
            gram + 1e-3 * np.trace(gram) / order * np.eye(order), lagged.T @ x[-window:]
        )
        return coefficients @ x[-order:][::-1]

    print(f"alpha = 0: RMS(e) {rms(np.cumsum(d0)):.4f}; D0 RMS {rms(d0):.4f}, S RMS {rms(slope):.3f}")
    for name, predict in (("last", last), ("linear", linear), ("AR(4)", ar4)):
        errors_d0 = [d0[i] - predict(d0[:i]) for i in range(100, n)]
        errors_s = [slope[i] - predict(slope[:i]) for i in range(100, n)]
        e, residuals = 0.0, []
        for i in range(n):
            guess_d0, guess_s = (predict(d0[:i]), predict(slope[:i])) if i > 2 else (0.0, 1.0)
            damping = (0.3 * np.mean(np.abs(slope[max(0, i - 50) : i]))) ** 2 if i else 1.0
            alpha = np.clip(-(e + guess_d0) * guess_s / (guess_s**2 + damping), -0.2, 0.2)
            e += d0[i] + alpha * slope[i]
            residuals.append(e)
        print(
            f"open loop, {name:7s}: prediction error D0 {rms(errors_d0):.4f}, S {rms(errors_s):.3f}; "
            f"one trial per step with the exact past: RMS(e) {rms(residuals[100:]):.4f}"
        )

    cumulative_d0, cumulative_s = np.cumsum(d0), np.cumsum(slope)
    z, c = cumulative_d0 - cumulative_d0.mean(), cumulative_s - cumulative_s.mean()
    best = -(z @ c) / (c @ c)
    print(f"best fixed alpha (linear model): {best:.4f}, RMS(e) {rms(z + best * c):.4f}")

    def closed_loop(threshold, damping=0.3, trust=0.05, bound=0.2, probe=0.002):
        e, residuals, evaluations, seen_d0, seen_s = 0.0, [], 0, [], []
        alpha_before, scale = 0.0, max(abs(slope[0]), 1e-6)
        for i in range(n):
            guess_d0, guess_s = ar4(seen_d0), (ar4(seen_s) if seen_s else 0.0)
            damped = guess_s**2 + (damping * scale) ** 2
            alpha = np.clip(
                -(e + guess_d0) * guess_s / damped,
                max(-bound, alpha_before - trust),
                min(bound, alpha_before + trust),
            )
            first = e + d0[i] + alpha * slope[i] + noise * rng.standard_normal()
            evaluations += 4
            if abs(first) > threshold or len(seen_s) < 70:
                move = -first * guess_s / damped
                move = move if abs(move) >= probe else probe * (1 if move >= 0 else -1)
                second_alpha = np.clip(alpha + np.clip(move, -trust, trust), -bound, bound)
                second = e + d0[i] + second_alpha * slope[i] + noise * rng.standard_normal()
                evaluations += 2
                measured = (second - first) / (second_alpha - alpha) if second_alpha != alpha else guess_s
                seen_s.append(measured)
                seen_d0.append(first - e - alpha * measured)
                e, alpha_before = (second, second_alpha) if abs(second) < abs(first) else (first, alpha)
            else:
                seen_s.append(guess_s)
                seen_d0.append(first - e - alpha * guess_s)
                e, alpha_before = first, alpha
            bounded = min(max(abs(seen_s[-1]), 1e-3 * scale), 10 * scale)
            scale = float(np.exp(0.95 * np.log(scale) + 0.05 * np.log(bounded)))
            residuals.append(e)
        return rms(residuals[100:]), evaluations / n

    for threshold in (0.0, tolerance, 2 * tolerance, 4 * tolerance):
        for damping in (0.3, 1.0):
            result, evaluations = closed_loop(threshold, damping)
            print(
                f"closed loop, second trial above {threshold:g} kJ/mol, damping {damping}: "
                f"RMS(e) {result:.4f}, {evaluations:.2f} force evaluations per step"
            )


if __name__ == "__main__":
    main()
