"""The issue-17 identification benchmark, Python side: the same cost as
benches/manipulator_identify.rs minimised with scipy from the same starts, the two sides
timed interleaved, the side-by-side report.

    python benches/manipulator_identify.py --rust EXE [--quick] [--reps N]
        [--weighting inverse-variance|uniform] [--out DIR] [--report FILE]

It starts the Rust side (EXE --serve), which simulates the problem and writes
DIR/problem-<weighting>.json (the two poses' M, K0, pairs, motors, lines; the cost's terms;
the starts) and its own results. This side rebuilds the model FRF from those matrices
(numpy: per line the n x n complex system Z = s^2 M + s C + K solved for P R,
G = s (P R)^T Z^-1 P R) and the paper's cost V (eq. (15), the same formula), checks that V
agrees with the Rust side's at reference points (nominal, truth, some starts; 1e-9
relative, else exit status 1), checks its analytic gradient against finite differences,
then times:

* one core: the Rust side's identify on 1 thread and scipy's loop over the starts in this
  process, both pinned to the same core (sched_setaffinity), alternately, --reps rounds;
* all cores: identify on every thread and a multiprocessing Pool (one worker per core,
  started before the timing) over the starts, alternately, --reps rounds.

The scipy method: scipy.optimize.minimize(V, x0, jac=True, method="BFGS") with the analytic
gradient of V (dG/d ln k_s = -s k_s a_s^T a_s, dG/d ln c_s = -s^2 c_s a_s^T a_s,
a_s = e_s^T Z^-1 P R: one solve per line serves V and all 24 derivatives, as on the Rust
side). Not least_squares: V is a sum of p-means (square roots of weighted mean squares),
not a sum of squares; the Rust side minimises it by majorisation (reweighted LM rounds),
least_squares on one round's reweighted residuals would be another problem. BFGS on V
itself is the general-purpose way to minimise "the same cost".

Ratios are reported, never asserted; exit status 1 only when the two sides' V disagree.
"""

import json
import multiprocessing
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import scipy
from scipy.optimize import minimize

#: 20 / ln 10: dB per neper (cost.rs DB_PER_NEPER).
DB_PER_NEPER = 20.0 / np.log(10.0)
#: The two sides' V at the same parameters must agree to this (relative).
TOL_V_REL = 1e-9
#: Final costs within this factor of the best count as the same minimum (identify.rs
#: GOOD_COST_RATIO).
GOOD_COST_RATIO = 1.1
#: BFGS's stopping rule: the largest |dV/d ln theta| [dB] below this. V's last digits at
#: the minimum then no longer move (checked: 1e-7 gives the same V to 1e-9 and costs more
#: iterations).
BFGS_GTOL = 1e-6
BFGS_MAXITER = 20000
#: Target of the issue: scipy time / flexid time at least this, at equal or lower V.
TARGET = 20.0


class Pose:
    """One pose of the linear model: Z(s) = s^2 M + K0 + sum_s (k_s + s c_s) e_s e_s^T."""

    def __init__(self, d):
        n = d["coords"]
        self.n = n
        self.mass = np.array(d["mass_kgm2"], dtype=float)
        self.k0 = np.array(d["gravity_stiffness_nm_per_rad"], dtype=float)
        pairs = d["pairs"]
        self.pa = np.array([a for a, _ in pairs])
        # the second coordinate of a pair; n (a zero row appended to X) for a bearing
        self.pm = np.array([n if m is None else m for _, m in pairs])
        e = np.zeros((len(pairs), n))
        for i, (a, m) in enumerate(pairs):
            e[i, a] += 1.0
            if m is not None:
                e[i, m] -= 1.0
        # e_s e_s^T per pair (S, n, n)
        self.ee = np.einsum("si,sj->sij", e, e)
        self.motors = np.array(d["motor_coords"])
        self.r = np.array(d["gear_ratios"], dtype=float)
        self.pr = np.zeros((n, len(self.r)))
        self.pr[self.motors, np.arange(len(self.r))] = self.r
        self.f = np.array(d["f_hz"], dtype=float)
        self.s = 2j * np.pi * self.f
        # s^2 M + K0 per line (L, n, n), constant
        self.z0 = self.s[:, None, None] ** 2 * self.mass + self.k0

    def solve(self, k, c):
        """X = Z^-1 P R per line (L, n, N)."""
        w = k[None, :] + self.s[:, None] * c[None, :]  # (L, S)
        z = self.z0 + np.tensordot(w, self.ee, axes=1)
        return np.linalg.solve(z, self.pr)

    def elements(self, li, ni, mi):
        """The flat indices into X of G's elements (line, n, m) and their factors s r_n:
        G_nm = s r_n X[motor n, m]; the flat indices into an (L, N, N) array."""
        n_ax = len(self.r)
        ix = (li * self.n + self.motors[ni]) * n_ax + mi
        return ix, self.s[li] * self.r[ni], (li * n_ax + ni) * n_ax + mi


class Problem:
    """The cost V(ln theta) of problem.json and its gradient."""

    def __init__(self, prob):
        self.p = float(prob["p"])
        self.poses = [Pose(d) for d in prob["poses"]]
        self.axes = prob["axes"]
        terms = prob["terms"]
        self.nterms = len(terms)
        # per pose: the flattened (line, n, m) of every term's lines, alpha, measured dB,
        # term index
        self.flat = []
        for r in range(len(self.poses)):
            li, ni, mi, al, db, ti = [], [], [], [], [], []
            for t_i, t in enumerate(terms):
                if t["pose"] != r:
                    continue
                k = len(t["lines"])
                li += t["lines"]
                ni += [t["n"]] * k
                mi += [t["m"]] * k
                al += t["alpha"]
                db += t["measured_db"]
                ti += [t_i] * k
            li, ni, mi = np.array(li, dtype=int), np.array(ni, dtype=int), np.array(mi, dtype=int)
            ix, fac, iw = self.poses[r].elements(li, ni, mi)
            self.flat.append((ix, fac, iw, np.array(al), np.array(db), np.array(ti, dtype=int)))
        self.alpha_sum = np.zeros(self.nterms)
        for t_i, t in enumerate(terms):
            self.alpha_sum[t_i] = sum(t["alpha"])

    def value(self, theta):
        """V at ln theta."""
        return self._eval(theta, False)[0]

    def value_and_grad(self, theta):
        """V and dV/d ln theta."""
        return self._eval(theta, True)

    def _eval(self, theta, grad):
        theta = np.asarray(theta, dtype=float)
        ns = len(theta) // 2
        k, c = np.exp(theta[:ns]), np.exp(theta[ns:])
        p = self.p
        solved = []
        ssum = np.zeros(self.nterms)
        errs = []
        for pose, (ix, fac, iw, al, db, ti) in zip(self.poses, self.flat):
            x = pose.solve(k, c)
            gel = fac * np.take(x, ix)
            e = DB_PER_NEPER * np.log(np.abs(gel)) - db
            ssum += np.bincount(ti, weights=al * np.abs(e) ** p, minlength=self.nterms)
            solved.append((x, gel))
            errs.append(e)
        s_t = ssum / self.alpha_sum
        v = float(np.sum(s_t ** (1.0 / p)))
        if not grad:
            return v, None
        # dV/dE_j = S_t^(1/p - 1) alpha_j |E_j|^(p-1) sign(E_j) / sum alpha_t
        outer = np.maximum(s_t, 1e-300) ** (1.0 / p - 1.0) / self.alpha_sum
        gk = np.zeros(ns)
        gc = np.zeros(ns)
        for pose, (ix, fac, iw, al, db, ti), (x, gel), e in zip(self.poses, self.flat, solved, errs):
            dv_de = outer[ti] * al * np.abs(e) ** (p - 1.0) * np.sign(e)
            # dE/d ln theta = DB Re(dG_nm / G_nm): the weights dV/dE / G_nm per element
            w = np.zeros((len(pose.f), self.axes, self.axes), dtype=complex)
            w.reshape(-1)[iw] = dv_de / gel
            xp = np.concatenate([x, np.zeros((x.shape[0], 1, x.shape[2]))], axis=1)
            a = xp[:, pose.pa, :] - xp[:, pose.pm, :]  # a_s per line (L, S, N)
            q = np.einsum("lsn,lsn->ls", a @ w, a)  # sum_nm W_nm a_n a_m
            gk += DB_PER_NEPER * np.real(-(pose.s[:, None] * q).sum(axis=0)) * k
            gc += DB_PER_NEPER * np.real(-(pose.s[:, None] ** 2 * q).sum(axis=0)) * c
        return v, np.concatenate([gk, gc])


def fit_start(prob, x0):
    """One start: BFGS on V with its analytic gradient; (final V, ln theta, nfev, nit,
    converged). A trial step of the line search far out (exp overflows) gives a V that
    is not finite, which the line search rejects; numpy's warnings about it are silenced.
    """
    with np.errstate(all="ignore"):
        r = minimize(
            prob.value_and_grad, np.asarray(x0, dtype=float), jac=True, method="BFGS",
            options={"gtol": BFGS_GTOL, "maxiter": BFGS_MAXITER},
        )
    v = float(r.fun)
    # a start whose line search ended on a non-finite V has failed (flexid's failed starts
    # are reported the same way)
    return (v if np.isfinite(v) else np.inf), r.x, int(r.nfev), int(r.nit), bool(r.success)


def fit_all(prob, starts):
    return [fit_start(prob, x0) for x0 in starts]


# ---------------------------------------------------------------- the pool (all cores)
_pool_problem = None


def _pool_init(path):
    global _pool_problem
    _pool_problem = Problem(json.loads(Path(path).read_text()))


def _pool_fit(x0):
    return fit_start(_pool_problem, x0)


class RustSide:
    """The Rust side answering one timed identification per request (--serve)."""

    def __init__(self, exe, out, quick, weighting, starts):
        cmd = [exe, "--out", str(out), "--weighting", weighting, "--serve"]
        cmd += ["--quick"] if quick else []
        cmd += ["--starts", str(starts)] if starts else []
        self.p = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        line = self.p.stdout.readline().strip()
        if line != "ready":
            raise RuntimeError(f"the Rust side did not start: {line!r}")

    def run(self, threads):
        self.p.stdin.write(f"run {threads}\n")
        self.p.stdin.flush()
        line = self.p.stdout.readline().strip()
        if not line.startswith("{"):
            raise RuntimeError(f"the Rust side answered {line!r}")
        return json.loads(line)

    def close(self):
        try:
            self.p.stdin.write("quit\n")
            self.p.stdin.close()
        except OSError:
            pass
        self.p.wait()


def stiffness_errors(theta, truth):
    ns = len(truth) // 2
    return np.exp(np.asarray(theta[:ns]) - np.asarray(truth[:ns])) - 1.0


def fmt_t(s):
    return f"{s * 1e3:.0f} ms" if s < 1 else f"{s:.2f} s"


def main():
    args = sys.argv[1:]

    def opt(name, default=None):
        return args[args.index(name) + 1] if name in args else default

    quick = "--quick" in args
    exe = opt("--rust")
    if exe is None:
        print("usage: manipulator_identify.py --rust EXE [--quick] [--reps N] [--starts N] "
              "[--weighting W] [--out DIR] [--report FILE]", file=sys.stderr)
        return 2
    weighting = opt("--weighting", "inverse-variance")
    out = Path(opt("--out", "target/bench/manipulator"))
    report = opt("--report")
    reps = int(opt("--reps", "1" if quick else "3"))
    starts_arg = opt("--starts")
    failures = []

    allowed = sorted(os.sched_getaffinity(0))
    core = allowed[-1]  # the last one (core 0 takes most interrupts)
    t_setup = time.perf_counter()
    side = RustSide(exe, out, quick, weighting, starts_arg)
    prob_path = out / f"problem-{weighting}.json"
    pj = json.loads(prob_path.read_text())
    rust = json.loads((out / f"rust-{weighting}.json").read_text())
    rr = rust["result"]
    with np.errstate(divide="ignore"):  # a damping at zero: ln = -inf, exp(-inf) = 0
        rust_theta = np.log(np.array(rr["best_stiffness_nm_per_rad"] + rr["best_damping_nms_per_rad"]))
    prob = Problem(pj)
    starts = np.array(pj["starts"])
    nstarts = len(starts)
    truth = np.array(pj["truth_theta"])
    print(
        f"problem: {len(pj['poses'])} poses, {pj['poses'][0]['coords']} coordinates, "
        f"{len(pj['poses'][0]['f_hz'])} lines, {len(pj['terms'])} terms, {len(truth)} parameters, "
        f"{nstarts} starts, {weighting} weights (Rust set-up {time.perf_counter() - t_setup:.1f} s)"
    )

    # ---- agreement: V at the Rust side's reference points, the gradient by differences
    worst = 0.0
    for c in pj["checks"]:
        v = prob.value(c["theta"])
        rel = abs(v - c["cost"]) / abs(c["cost"])
        worst = max(worst, rel)
        ok = rel <= TOL_V_REL
        print(f"  V at {c['what']}: flexid {c['cost']:.12g}, numpy {v:.12g}, rel {rel:.1e} {'ok' if ok else 'DISAGREE'}")
        if not ok:
            failures.append(f"V at {c['what']}")
    v_best_rust = prob.value(rust_theta)
    rel = abs(v_best_rust - rust["result"]["best_cost"]) / rust["result"]["best_cost"]
    worst = max(worst, rel)
    print(f"  V at flexid's best: flexid {rust['result']['best_cost']:.12g}, numpy {v_best_rust:.12g}, rel {rel:.1e}")
    if rel > TOL_V_REL:
        failures.append("V at flexid's best")
    x = starts[min(1, nstarts - 1)]
    _, g = prob.value_and_grad(x)
    h = 1e-6
    fd = np.array([(prob.value(x + h * np.eye(len(x))[j]) - prob.value(x - h * np.eye(len(x))[j])) / (2 * h) for j in range(len(x))])
    grad_err = float(np.max(np.abs(fd - g)) / np.max(np.abs(g)))
    print(f"  numpy gradient against central differences: max |diff| / max |grad| {grad_err:.1e}")
    if not grad_err < 1e-5:
        failures.append("numpy gradient")
    if failures:
        side.close()
        print(f"bench: the two sides DISAGREE: {', '.join(failures)}", file=sys.stderr)
        return 1

    # ---- one core: both pinned to the same core, alternately
    os.sched_setaffinity(0, {core})
    os.sched_setaffinity(side.p.pid, {core})
    fit_all(prob, starts[:1])  # warm-up (the Rust side warmed up writing its results)
    t1_rs, t1_py, rs_runs = [], [], []
    py = None
    for i in range(reps):
        rs_runs.append(side.run(1))
        t1_rs.append(rs_runs[-1]["seconds"])
        t0 = time.perf_counter()
        py = fit_all(prob, starts)
        t1_py.append(time.perf_counter() - t0)
        print(f"  one core, round {i + 1}/{reps}: flexid {fmt_t(t1_rs[-1])}, scipy {fmt_t(t1_py[-1])}, ratio {t1_py[-1] / t1_rs[-1]:.1f}x")

    # ---- all cores: identify on every thread, a Pool of one worker per core
    os.sched_setaffinity(0, set(allowed))
    os.sched_setaffinity(side.p.pid, set(allowed))
    workers = len(allowed)
    tn_rs, tn_py = [], []
    ctx = multiprocessing.get_context("fork")
    with ctx.Pool(workers, initializer=_pool_init, initargs=(str(prob_path),)) as pool:
        pool.map(_pool_fit, starts[:workers], chunksize=1)  # warm-up: every worker
        for i in range(reps):
            r = side.run(0)
            rs_runs.append(r)
            tn_rs.append(r["seconds"])
            t0 = time.perf_counter()
            pyn = pool.map(_pool_fit, list(starts), chunksize=1)
            tn_py.append(time.perf_counter() - t0)
            print(f"  all {workers} cores, round {i + 1}/{reps}: flexid {fmt_t(tn_rs[-1])}, scipy {fmt_t(tn_py[-1])}, ratio {tn_py[-1] / tn_rs[-1]:.1f}x")
    side.close()
    # the pool's results are the serial ones (same starts, same arithmetic)
    pool_same = all(a[0] == b[0] or abs(a[0] - b[0]) <= 1e-12 * abs(a[0]) for a, b in zip(py, pyn))

    # ---- results
    rust_costs = np.array([np.inf if s["cost"] is None else s["cost"] for s in rr["starts"]])
    py_costs = np.array([r[0] for r in py])
    rust_best, py_best = float(rust_costs.min()), float(py_costs.min())
    overall = min(rust_best, py_best)
    good_rs = int(np.sum(rust_costs <= GOOD_COST_RATIO * overall))
    good_py = int(np.sum(py_costs <= GOOD_COST_RATIO * overall))
    py_theta = py[int(np.argmin(py_costs))][1]
    err_rs = np.array(rr["stiffness_errors"])
    err_py = stiffness_errors(py_theta, truth)
    py_nfev = sum(r[2] for r in py)
    py_nit = sum(r[3] for r in py)
    py_unconverged = sum(not r[4] for r in py)
    py_failed = int(np.sum(~np.isfinite(py_costs)))
    rust_failed = int(np.sum(~np.isfinite(rust_costs)))
    rust_evals = sum(s["evaluations"] for s in rr["starts"])
    consistent = all(abs(r["cost"] - rust_best) <= 1e-12 * rust_best for r in rs_runs)
    # the two bests compared: stiffnesses (identified), dampings (some left free by the data)
    ns = len(truth) // 2
    d_k = float(np.max(np.abs(np.exp(rust_theta[:ns] - py_theta[:ns]) - 1.0)))
    d_c = float(np.max(np.abs(np.exp(rust_theta[ns:] - py_theta[ns:]) - 1.0)))

    def ratios(tr, tp):
        q = [p / r for p, r in zip(tp, tr)]
        return float(np.median(q)), float(min(q)), float(max(q))

    r1, rn = ratios(t1_rs, t1_py), ratios(tn_rs, tn_py)
    lower = rust_best <= py_best * (1.0 + 1e-9)
    rel_best = rust_best / py_best - 1.0
    if abs(rel_best) <= 1e-9:
        verdict = f"equal to round-off (flexid / scipy - 1 = {rel_best:+.1e})"
    elif lower:
        verdict = f"flexid lower ({rel_best:+.1e})"
    else:
        verdict = f"flexid HIGHER ({rel_best:+.1e})"
    load = os.getloadavg()
    cpu = "unknown CPU"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    names = pj["parameter_names"]
    lines = [
        f"# Issue-17 identification: flexid against scipy on the same cost{' [quick]' if quick else ''}",
        "",
        f"The reference robot ({pj['robot']}: {pj['axes']} axes, {ns} spring-damper pairs, {len(truth)} parameters), "
        f"two identification poses simulated as in `crates/flexid-core/tests/manipulator_identification.rs` "
        f"({len(pj['poses'][0]['f_hz'])} lines of 2-300 Hz each), the paper's cost V (eq. (15), p = {pj['p']:g}, "
        f"{len(pj['terms'])} terms, **{weighting}** weights) in the **continuous** model form "
        f"(G = s (PR)^T Z^-1 PR; the sampled form's zero-order-hold plant is not rebuilt in numpy, so both sides "
        f"minimise exactly the same function), {nstarts} starts (the Latin hypercube of `identify::start_design`, spread "
        f"{pj['spread']:g}, seed {pj['seed']}), the same starts on both sides.",
        "",
        f"* flexid: `manipulator::identify` (majorised reweighted Levenberg-Marquardt, analytic Jacobian), "
        f"threads 1 and 0 (every core).",
        f"* scipy {scipy.__version__} / numpy {np.__version__} (Python {platform.python_version()}): "
        f"`scipy.optimize.minimize(V, x0, jac=True, method='BFGS', gtol={BFGS_GTOL:g})` per start, V and its "
        f"analytic gradient in numpy (per line one batched `np.linalg.solve` of the {pj['poses'][0]['coords']}x"
        f"{pj['poses'][0]['coords']} complex Z for P R; dG/d ln k_s = -s k_s a_s^T a_s, dG/d ln c_s = -s^2 c_s a_s^T a_s); "
        f"all cores: a `multiprocessing` Pool of {workers} workers over the starts (started before the timing).",
        f"* Machine: {os.cpu_count()} cores ({cpu}); one core = both sides pinned to core {core} "
        f"(sched_setaffinity), BLAS/OpenMP one thread; load average at the end {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} "
        f"(1 / 5 / 15 min: other work shares the machine); {reps} round(s), each one flexid run then one scipy run; "
        f"ratio = scipy / flexid per round, median [min, max]. Ratios are reported, not asserted.",
        f"* Agreement: V at nominal, truth, starts and flexid's best: max rel difference {worst:.1e} "
        f"(tolerance {TOL_V_REL:g}); numpy gradient against central differences {grad_err:.1e}.",
        "",
        "| | flexid | scipy BFGS | ratio median [min, max] |",
        "|---|---|---|---|",
        f"| wall time, one core | {fmt_t(float(np.median(t1_rs)))} | {fmt_t(float(np.median(t1_py)))} | **{r1[0]:.1f}x** [{r1[1]:.1f}, {r1[2]:.1f}] |",
        f"| wall time, all {workers} cores | {fmt_t(float(np.median(tn_rs)))} | {fmt_t(float(np.median(tn_py)))} | **{rn[0]:.1f}x** [{rn[1]:.1f}, {rn[2]:.1f}] |",
        f"| best final V [dB] | {rust_best:.9f} | {py_best:.9f} | {verdict} |",
        f"| starts at the best minimum (V within 10 % of {overall:.6f}) | {good_rs}/{nstarts} | {good_py}/{nstarts} | |",
        f"| max stiffness error of the best against the truth | {100 * np.max(np.abs(err_rs)):.3f} % | {100 * np.max(np.abs(err_py)):.3f} % | the two bests' stiffnesses differ by {100 * d_k:.2e} % at most, dampings by {100 * d_c:.3g} % (some dampings are left free by these data) |",
        f"| model evaluations, all starts | {rust_evals} (V passes and Jacobian passes) | {py_nfev} (V + gradient), {py_nit} iterations; {py_unconverged} starts ended without BFGS's convergence (precision loss in the line search) | |",
        f"| failed starts (final V not finite: for BFGS a line search whose trial step overflowed exp(ln theta)) | {rust_failed} | {py_failed} | |",
        "",
        f"Target (issue 17): at least {TARGET:g}x on one core at equal or lower final V: "
        f"**{'met' if r1[0] >= TARGET and lower else 'not met'}** (one core {r1[0]:.1f}x, all cores {rn[0]:.1f}x).",
        "",
        "Times per round [s]: flexid one core " + ", ".join(f"{t:.3f}" for t in t1_rs)
        + "; scipy one core " + ", ".join(f"{t:.3f}" for t in t1_py)
        + "; flexid all cores " + ", ".join(f"{t:.3f}" for t in tn_rs)
        + "; scipy all cores " + ", ".join(f"{t:.3f}" for t in tn_py) + ".",
        f"flexid's runs all reached the same best V: {'yes' if consistent else 'NO'}; the pool's results equal the serial ones: {'yes' if pool_same else 'NO'}.",
        "",
        "Stiffness errors of the two bests against the truth:",
        "",
        "| parameter | flexid | scipy |",
        "|---|---|---|",
    ]
    for j in range(ns):
        lines.append(f"| {names[j]} | {100 * err_rs[j]:+.3f} % | {100 * err_py[j]:+.3f} % |")
    lines += [
        "",
        "Final V per start [dB] (flexid / scipy, evaluations flexid / scipy):",
        "",
        "| start | flexid V | scipy V | flexid evaluations | scipy evaluations |",
        "|---|---|---|---|---|",
    ]
    for i in range(nstarts):
        lines.append(
            f"| {i} | {rust_costs[i]:.6f} | {py_costs[i]:.6f} | {rr['starts'][i]['evaluations']} | {py[i][2]} |"
        )
    text = "\n".join(lines) + "\n"
    print()
    print("\n".join(lines[: lines.index("Stiffness errors of the two bests against the truth:")]))
    if report:
        Path(report).parent.mkdir(parents=True, exist_ok=True)
        Path(report).write_text(text)
        print(f"written to {report}")
    (out / f"scipy-{weighting}.json").write_text(json.dumps({
        "method": "BFGS", "gtol": BFGS_GTOL,
        "seconds_one_core": t1_py, "seconds_all_cores": tn_py,
        "rust_seconds_one_core": t1_rs, "rust_seconds_all_cores": tn_rs,
        "starts": [{"cost": r[0], "nfev": r[2], "nit": r[3]} for r in py],
        "best_cost": py_best, "best_theta": list(py_theta),
    }, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
