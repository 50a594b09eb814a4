"""The comparison benchmark, Python side: the same computations as benches/compare.rs with
scipy/numpy, on the files the Rust side wrote, then the side-by-side table.

    python benches/compare.py DATA_DIR [--report target/bench/compare.md]

Each side times only its own computation, in-process (no file I/O, no start-up), with the
median over several repetitions after a warm-up call. scripts/bench.sh pins both processes
to one core and sets OMP/OpenBLAS/MKL to one thread.

Exit status 1 when the two sides' numbers disagree (a correctness check); the timing ratios
and targets are reported, never asserted.
"""

import json
import os
import platform
import sys
import subprocess
import time
from pathlib import Path

import numpy as np
import scipy
from scipy.optimize import least_squares
from scipy.signal import csd, welch

# Agreement tolerances (both sides compute the same thing in double precision).
TOL_H_REL = 1e-9  # H1 / periodic H, relative
TOL_COH_ABS = 1e-9  # coherence, absolute
TOL_VAR_REL = 1e-6  # periodic variance, relative (a difference of sums)
TOL_RES_REL = 1e-7  # fit residual vector, max |diff| / RMS


def load(d, name, rows=None):
    v = np.fromfile(d / name, dtype="<f8")
    return v if rows is None else v.reshape(rows, -1)


class RustSide:
    """The Rust side as a process answering one timed run per request (compare.rs
    --serve): started here, so that the two sides alternate run by run."""

    def __init__(self, exe, data, quick):
        cmd = [exe, "--out", str(data), "--serve"] + (["--quick"] if quick else [])
        self.p = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        line = self.p.stdout.readline().strip()
        if line != "ready":
            raise RuntimeError(f"the Rust side did not start: {line!r}")

    def run(self, what):
        self.p.stdin.write(what + "\n")
        self.p.stdin.flush()
        return float(self.p.stdout.readline())

    def close(self):
        try:
            self.p.stdin.write("quit\n")
            self.p.stdin.close()
        except OSError:
            pass
        self.p.wait()


def interleaved(rounds, rust, what, f):
    """`rounds` rounds of one Rust run and one Python run each (after one warm-up of the
    Python side); the times of both sides, per round, and the last Python result."""
    out = f()  # warm-up (the Rust side warmed up while generating the data)
    tr, tp = [], []
    for _ in range(rounds):
        tr.append(rust.run(what))
        t0 = time.perf_counter()
        out = f()
        tp.append(time.perf_counter() - t0)
    return tr, tp, out


def timed(reps, f):
    out = f()  # warm-up
    t = []
    for _ in range(reps):
        t0 = time.perf_counter()
        out = f()
        t.append(time.perf_counter() - t0)
    return t, out


# ---------------------------------------------------------------- H1 with coherence
def h1_scipy(u, y, fs, nperseg, noverlap):
    kw = dict(fs=fs, window="hann", nperseg=nperseg, noverlap=noverlap, detrend="constant")
    _, puu = welch(u, **kw)
    _, pyy = welch(y, **kw)
    _, pyu = csd(u, y, **kw)  # conj(U) Y
    h = pyu / puu
    coh = np.abs(pyu) ** 2 / (puu * pyy)
    return h, coh


# ---------------------------------------------------------------- periodic estimator
def periodic_numpy(u, y, n, periods, transient, lines):
    seg = slice(transient * n, (transient + periods) * n)
    U = np.fft.rfft(u[seg].reshape(periods, n), axis=1)[:, lines] / n
    Y = np.fft.rfft(y[seg].reshape(periods, n), axis=1)[:, lines] / n
    mu, my = U.mean(axis=0), Y.mean(axis=0)
    du, dy = U - mu, Y - my
    # the ramp of a constant acceleration (velocity output; flexid's src/frf/ramp.rs): the
    # least-squares slope b of the period means, and (b/n) / (e^{-j 2 pi k/n} - 1) off each
    # line's mean (the same in every period: the deviations above are unchanged)
    dc = y[seg].reshape(periods, n).mean(axis=1)
    m = np.arange(periods) - 0.5 * (periods - 1)
    b = (m * dc).sum() / (m * m).sum() if periods > 1 else 0.0
    k = np.asarray(lines)
    my = my - (b / n) / (np.exp(-2j * np.pi * k / n) - 1.0)
    m2u = (du.real**2 + du.imag**2).sum(axis=0)
    m2y = (dy.real**2 + dy.imag**2).sum(axis=0)
    m2yu = (dy * du.conj()).sum(axis=0)
    p = periods
    h = my / mu
    su, sy, syu = m2u / (p - 1), m2y / (p - 1), m2yu / (p - 1)
    var = (sy + np.abs(h) ** 2 * su - 2.0 * (h.conj() * syu).real) / (p * np.abs(mu) ** 2)
    suu = np.abs(mu) ** 2 + m2u / p
    syy = np.abs(my) ** 2 + m2y / p
    syu_ = my * mu.conj() + m2yu / p
    coh = np.clip(np.abs(syu_) ** 2 / (suu * syy), 0.0, 1.0)
    return h, var, coh


# ---------------------------------------------------------------- the chain fit
class ChainProblem:
    """The weighted log-complex residual of flexid's fit (src/identify/fit.rs, problem.rs):
    the exact ZOH-sampled position response of the chain in pole/residue form, times the
    backward difference, over the measured FRF; parameters theta = ln(J.., c.., d..)."""

    def __init__(self, freq, h, var, fs, masses):
        ok = (freq > 0) & np.isfinite(freq) & np.isfinite(var) & (var >= 0)
        ok &= np.isfinite(h) & (np.abs(h) > 0)
        freq, h, var = freq[ok], h[ok], var[ok]
        ts = 1.0 / fs
        th = 2.0 * np.pi * freq * ts
        z = np.exp(1j * th)
        zm1 = -2.0 * np.sin(0.5 * th) ** 2 + 1j * np.sin(th)  # z - 1 without cancellation
        g = zm1 / (z * ts)  # backward difference, no delay
        sig = np.sqrt(var / 2.0) / np.abs(h)
        known = sig[var > 0]
        fallback = np.sort(known)[len(known) // 2] if len(known) else 1e-2
        sig = np.where(var > 0, sig, fallback)
        self.n, self.ts, self.lines = masses, ts, len(freq)
        self.zm1 = zm1
        self.k = g / h
        self.gamma = ts * ts * (z + 1.0) / (2.0 * zm1 * zm1)
        self.w = 1.0 / sig
        self.fail = np.full(2 * self.lines, 1e10)

    def ladder(self, s, J, c, d):
        """Driving-point impedance Z(s) and dZ/ds (vectorised over s)."""
        n = self.n
        z = s * J[n - 1]
        dz = np.full_like(s, J[n - 1])
        for i in range(n - 2, -1, -1):
            k = d[i] + c[i] / s
            dk = -c[i] / (s * s)
            den = k + z
            q = k * z / den
            dq = (dk * z * z + dz * k * k) / (den * den)
            z = s * J[i] + q
            dz = dq + J[i]
        return z, dz

    def residuals(self, theta):
        with np.errstate(all="ignore"):  # far-off trial points: non-finite -> self.fail
            return self._residuals(theta)

    def _residuals(self, theta):
        n = self.n
        if not np.all(np.isfinite(theta)) or np.any(np.abs(theta) > 700):
            return self.fail
        e = np.exp(theta)
        J, c, d = e[:n], e[n : 2 * n - 1], e[2 * n - 1 :]
        # state matrix of the free chain: x = [positions, velocities]
        K = np.zeros((n, n))
        D = np.zeros((n, n))
        for i in range(n - 1):
            for M, v in ((K, c[i]), (D, d[i])):
                M[i, i] += v
                M[i + 1, i + 1] += v
                M[i, i + 1] -= v
                M[i + 1, i] -= v
        A = np.zeros((2 * n, 2 * n))
        A[:n, n:] = np.eye(n)
        A[n:, :n] = -K / J[:, None]
        A[n:, n:] = -D / J[:, None]
        try:
            eig = np.linalg.eigvals(A)
        except np.linalg.LinAlgError:
            return self.fail
        p = eig[np.argsort(np.abs(eig))][2:].astype(complex)  # drop the rigid body
        # one Newton step on Z(p) = 0 polishes the eigenvalues to full precision (flexid
        # iterates to convergence; the step is quadratic, one is enough from eig's accuracy)
        zz, dz = self.ladder(p, J, c, d)
        p = p - zz / dz
        _, dz = self.ladder(p, J, c, d)
        r = 1.0 / (p * dz)
        a, b = (p * self.ts).real, (p * self.ts).imag
        m = (np.expm1(a) * np.cos(b) - 2.0 * np.sin(0.5 * b) ** 2) + 1j * (np.exp(a) * np.sin(b))
        ra = r * m / p  # sampled residue: r/(s-p) -> ra/(z-q), q - 1 = m
        # pair the poles (conjugates, or two real ones) into real second-order sections in
        # w = z - 1, as flexid does: (n1 w + n0) / (w^2 + b1 w + b0)
        up = p.imag > 1e-12 * np.abs(p)
        real = np.abs(p.imag) <= 1e-12 * np.abs(p)
        if 2 * up.sum() + real.sum() != len(p) or real.sum() % 2:
            return self.fail
        a1 = np.concatenate([ra[up], ra[real][0::2]])
        a2 = np.concatenate([ra[up].conj(), ra[real][1::2]])
        m1 = np.concatenate([m[up], m[real][0::2]])
        m2 = np.concatenate([m[up].conj(), m[real][1::2]])
        n1, n0 = (a1 + a2).real, -(a1 * m2 + a2 * m1).real
        b1, b0 = -(m1 + m2).real, (m1 * m2).real
        w = self.zm1
        P = self.gamma * (1.0 / J.sum())
        for s in range(len(n1)):
            P = P + (n1[s] * w + n0[s]) / (w * (w + b1[s]) + b0[s])
        v = P * self.k
        out = np.empty(2 * self.lines)
        out[0::2] = self.w * (0.5 * np.log(v.real * v.real + v.imag * v.imag))
        out[1::2] = self.w * np.arctan2(v.imag, v.real)
        if not np.all(np.isfinite(out)):
            return self.fail
        return out


def fit_scipy(prob, starts, opt):
    best = None
    for x0 in starts:
        res = least_squares(
            prob.residuals,
            x0,
            method="lm",  # MINPACK, like the levenberg-marquardt crate (a port of lmder)
            x_scale="jac",  # MINPACK's own diagonal scaling, as the crate does
            ftol=opt["ftol"],
            xtol=opt["xtol"],
            gtol=opt["gtol"],
            # same iteration budget: lmdif also counts the n evaluations per Jacobian
            max_nfev=opt["max_evaluations"] * (len(x0) + 1),
        )
        cost = 2.0 * res.cost
        if np.isfinite(cost) and (best is None or cost < best[0]):
            best = (cost, res.x)
    return best


def param_error(theta, truth, n):
    k = 2 * n - 1  # J1..Jn, c1..c(n-1)
    return float(np.max(np.abs(np.exp(theta[:k] - truth[:k]) - 1.0)))


# ---------------------------------------------------------------- main
def main():
    args = sys.argv[1:]
    d = Path(args[0])
    report = Path(args[args.index("--report") + 1]) if "--report" in args else None
    side = None
    if "--rust" in args:
        side = RustSide(args[args.index("--rust") + 1], d, "--quick" in args)
    meta = json.loads((d / "meta.json").read_text())
    quick = meta["quick"]
    fs = meta["sample_rate_hz"]
    reps_fast, reps_fit = (5, 1) if quick else (30, 3)
    failures = []
    rows = []

    def check(what, value, tol):
        ok = bool(np.isfinite(value) and value <= tol)
        print(f"  agreement {what}: {value:.2e} (tolerance {tol:.0e}) {'ok' if ok else 'DISAGREE'}")
        if not ok:
            failures.append(what)
        return value

    med = lambda t: float(np.median(t))

    # H1
    m = meta["h1"]
    u, y = load(d, "h1_u.f64"), load(d, "h1_y.f64")
    f = lambda: h1_scipy(u, y, fs, m["nperseg"], m["overlap"])
    if side:
        t_rs, t_py, (h, coh) = interleaved(reps_fast, side, "h1", f)
    else:
        t_rs = m["rust_times_s"]
        t_py, (h, coh) = timed(reps_fast, f)
    rust = load(d, "h1_rust.f64", 3)
    hr, cr = rust[0] + 1j * rust[1], rust[2]
    h, coh = h[1:], coh[1:]  # flexid reports lines 1..nperseg/2
    print(f"H1 with coherence: {m['samples']} samples, nperseg {m['nperseg']}, overlap {m['overlap']}")
    e_h1 = check("H1 (max rel)", np.max(np.abs(hr - h) / np.abs(h)), TOL_H_REL)
    e_c1 = check("coherence (max abs)", np.max(np.abs(cr - coh)), TOL_COH_ABS)
    tr, tp = med(t_rs), med(t_py)
    rows.append(
        dict(
            what=f"Welch H1 + coherence ({m['samples']} samples, {m['nperseg']}-sample Hann, 50 %)",
            peer="scipy.signal welch x2 + csd",
            tr=tr, tp=tp, unit="Msamples/s", thr=m["samples"] / tr / 1e6,
            thp=m["samples"] / tp / 1e6, target=10.0,
            agree=f"H {e_h1:.1e} rel, coherence {e_c1:.1e}", ratios=ratios(t_rs, t_py, side),
        )
    )

    # periodic
    m = meta["periodic"]
    u, y = load(d, "ms_u.f64"), load(d, "ms_y.f64")
    lines = np.array(m["excited_lines"])
    args_p = (u, y, m["period_samples"], m["periods"], m["transient_periods"], lines)
    f = lambda: periodic_numpy(*args_p)
    if side:
        t_rs, t_py, (h, var, coh) = interleaved(reps_fast, side, "periodic", f)
    else:
        t_rs = m["rust_times_s"]
        t_py, (h, var, coh) = timed(reps_fast, f)
    rust = load(d, "per_rust.f64", 4)
    hr, vr, cr = rust[0] + 1j * rust[1], rust[2], rust[3]
    print(
        f"periodic: {m['transient_periods']}+{m['periods']} periods of {m['period_samples']}, "
        f"{len(lines)} lines"
    )
    e_hp = check("periodic H (max rel)", np.max(np.abs(hr - h) / np.abs(h)), TOL_H_REL)
    e_vp = check("periodic var (max rel)", np.max(np.abs(vr - var) / var), TOL_VAR_REL)
    e_cp = check("periodic coherence (max abs)", np.max(np.abs(cr - coh)), TOL_COH_ABS)
    samples = (m["periods"] + m["transient_periods"]) * m["period_samples"]
    tr, tp = med(t_rs), med(t_py)
    rows.append(
        dict(
            what=f"periodic FRF ({m['periods']} periods of {m['period_samples']}, {len(lines)} lines, with variance and coherence)",
            peer="numpy reshape + rfft + mean/var (+ ramp of the period means)",
            tr=tr, tp=tp, unit="Msamples/s", thr=samples / tr / 1e6, thp=samples / tp / 1e6,
            target=2.0, agree=f"H {e_hp:.1e} rel, var {e_vp:.1e} rel, coherence {e_cp:.1e}",
            ratios=ratios(t_rs, t_py, side),
        )
    )

    # fit
    m = meta["fit"]
    frf = load(d, "fit_frf.f64", 4)
    prob = ChainProblem(frf[0], frf[1] + 1j * frf[2], frf[3], fs, m["masses"])
    starts = load(d, "fit_starts.f64", m["starts"])
    truth = np.array(m["truth_theta"])
    print(f"fit: {m['masses']} masses, {m['starts']} starts, {prob.lines} lines")
    if prob.lines != m["lines"]:
        failures.append("fit lines")
    res_err = 0.0
    for name, th in (("truth", truth), ("init", np.array(m["init_theta"])), ("best", np.array(m["rust_theta"]))):
        rr = load(d, f"fit_res_{name}.f64")
        rp = prob.residuals(th)
        rms = np.sqrt(np.mean(rr**2))
        res_err = max(res_err, check(f"fit residual at {name} (max abs / RMS {rms:.3g})", np.max(np.abs(rr - rp)) / rms, TOL_RES_REL))
    t_py, t_rs = [], []
    for _ in range(reps_fit):
        if side:
            t_rs.append(side.run("fit"))
        t0 = time.perf_counter()
        prob = ChainProblem(frf[0], frf[1] + 1j * frf[2], frf[3], fs, m["masses"])
        best = fit_scipy(prob, starts, m)
        t_py.append(time.perf_counter() - t0)
    if not side:
        t_rs = m["rust_times_s"]
    cost_py, x_py = best
    err_py = param_error(x_py, truth, m["masses"])
    err_r = m["rust_param_error"]
    # the two optima, compared
    rel_opt = float(np.max(np.abs(np.exp(np.array(m["rust_theta"]) - x_py) - 1.0)))
    print(
        f"  cost: flexid {m['rust_cost']:.8e}, scipy {cost_py:.8e}; optima differ by {rel_opt:.2e} (max rel); "
        f"max param error flexid {err_r:.3e}, scipy {err_py:.3e}"
    )
    tr, tp = med(t_rs), med(t_py)
    rows.append(
        dict(
            what=f"{m['masses']}-mass fit, {m['starts']} starts, {prob.lines} lines",
            peer="scipy.optimize.least_squares (lm, 2-point Jacobian)",
            tr=tr, tp=tp, unit="starts/s", thr=m["starts"] / tr, thp=m["starts"] / tp,
            target=50.0,
            agree=f"residual {res_err:.1e}; max param error flexid {100 * err_r:.3f} %, scipy {100 * err_py:.3f} %",
            extra_ok=err_r <= err_py + 1e-4,
            ratios=ratios(t_rs, t_py, side),
        )
    )
    if side:
        side.close()

    # table
    cpu = "unknown CPU"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    head = (
        f"flexid vs scipy {scipy.__version__} / numpy {np.__version__} (Python {platform.python_version()}), "
        f"one core of {os.cpu_count()} ({cpu}); "
        + (
            f"the two sides interleaved run by run, {reps_fast} rounds (fit: {reps_fit}); ratio = peer / flexid per round, median [min, max]"
            if side
            else f"median of {reps_fast} runs (fit: Rust {len(meta['fit']['rust_times_s'])}, scipy {reps_fit}), one side after the other"
        )
        + (" [quick]" if quick else "")
    )
    out = [head, "", "| computation | peer | flexid (median) | peer (median) | throughput flexid / peer | ratio median [min, max] | target | met | agreement |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        rm, rlo, rhi = r["ratios"]
        met = rm >= r["target"] and r.get("extra_ok", True)
        out.append(
            f"| {r['what']} | {r['peer']} | {fmt_t(r['tr'])} | {fmt_t(r['tp'])} | "
            f"{r['thr']:.3g} / {r['thp']:.3g} {r['unit']} | **{rm:.1f}x** [{rlo:.1f}, {rhi:.1f}] | {r['target']:g}x | "
            f"{'yes' if met else 'no'} | {r['agree']} |"
        )
    text = "\n".join(out) + "\n"
    print()
    print(text)
    if report:
        report.parent.mkdir(parents=True, exist_ok=True)
        report.write_text(text)
        print(f"written to {report}")
    if failures:
        print(f"bench: the two sides DISAGREE: {', '.join(failures)}", file=sys.stderr)
        return 1
    return 0


def ratios(t_rust, t_peer, interleaved_run):
    """Median, min and max of peer/flexid: per round when the sides were interleaved,
    else of the medians (one value)."""
    if interleaved_run:
        r = [p / q for p, q in zip(t_peer, t_rust)]
    else:
        r = [float(np.median(t_peer)) / float(np.median(t_rust))]
    return float(np.median(r)), float(min(r)), float(max(r))


def fmt_t(s):
    return f"{s * 1e3:.1f} ms" if s < 1 else f"{s:.2f} s"


if __name__ == "__main__":
    sys.exit(main())
