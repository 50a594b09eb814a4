#!/usr/bin/env python3
"""IDIM-LS of the EMPS data, independently of flexid (numpy and scipy only).

Reads the MATLAB files itself (scipy.io.loadmat), converts the controller output to a
force (gtau * vir, the file's own gtau), and runs the method flexid documents for its
trajectory path (docs/diagnosis.md, "Trajectory data: rigid body with friction"), each
step with scipy's or numpy's own routine:

  cut-off   where the position's Welch PSD (of its first difference, divided by
            4 sin^2(pi f/fs)) smoothed by a 1/3-octave running median falls to twice its
            median over [fs/4, 0.45 fs]
  hold      force at k = mean of the forces of samples k-1 and k (zero-order hold)
  filter    scipy.signal.butter(4, fc, output="sos") + sosfiltfilt (odd padding over the
            filter's memory) on the position, the force and sign(qd)
  diff      numpy central differences
  samples   one in floor(fs/(2 fc)), the edges dropped, |qd| <= 3 sigma of the velocity
            noise (and the filter's spread around such samples) left out
  solve     numpy.linalg.lstsq; sigma^2 (X^T X)^-1; condition number; relative error

Prints one JSON object. Usage: idim_ls.py ESTIMATION.mat [CROSS_TEST.mat]
"""

import json
import sys

import numpy as np
import scipy.io
import scipy.signal


def load(path):
    d = scipy.io.loadmat(path)
    q = np.ravel(d["qm"]).astype(float)
    tau = np.ravel(d["vir"]).astype(float) * float(np.ravel(d["gtau"])[0])
    return q, tau


def segment(n):
    seg = 64
    while seg * 2 <= n // 8 and seg < 4096:
        seg *= 2
    return seg


def cutoff(q, tau, fs):
    dq = np.diff(q)
    f, pd = scipy.signal.welch(dq, fs=fs, window="hann", nperseg=segment(len(dq)),
                               noverlap=segment(len(dq)) // 2, detrend="constant")
    with np.errstate(divide="ignore", invalid="ignore"):
        pq = pd / (4.0 * np.sin(np.pi * f / fs) ** 2)
    band = (f >= 0.25 * fs) & (f <= 0.45 * fs)
    floor_q = np.median(pq[band])
    ft, pt = scipy.signal.welch(tau, fs=fs, window="hann", nperseg=segment(len(tau)),
                                noverlap=segment(len(tau)) // 2, detrend="constant")
    floor_t = np.median(pt[(ft >= 0.25 * fs) & (ft <= 0.45 * fs)])
    third = 2.0 ** (1.0 / 6.0)
    for k in range(1, len(f)):
        if f[k] >= 0.25 * fs:
            break
        win = (f[1:] >= f[k] / third) & (f[1:] <= f[k] * third)
        if np.median(pq[1:][win]) <= 2.0 * floor_q:
            return f[k], floor_q, floor_t
    return 0.25 * fs, floor_q, floor_t


def memory(sos, fs, fc):
    n = int(np.ceil(200.0 * fs / fc)) + 16
    x = np.zeros(n)
    x[0] = 1.0
    h = scipy.signal.sosfilt(sos, x)
    e = h ** 2
    tail = e.sum() - np.cumsum(e)
    return int(np.argmax(tail < 1e-9 * e.sum())) + 1


def zero_phase(sos, x, pad):
    return scipy.signal.sosfiltfilt(sos, x, padtype="odd", padlen=min(pad, len(x) - 1))


def central(x, fs):
    v = np.empty_like(x)
    a = np.empty_like(x)
    v[1:-1] = (x[2:] - x[:-2]) * fs / 2.0
    v[0], v[-1] = (x[1] - x[0]) * fs, (x[-1] - x[-2]) * fs
    a[1:-1] = (x[2:] - 2.0 * x[1:-1] + x[:-2]) * fs * fs
    a[0], a[-1] = a[1], a[-2]
    return v, a


class Processing:
    def __init__(self, q, tau, fs):
        self.fs = fs
        self.fc, self.floor_q, self.floor_t = cutoff(q, tau, fs)
        self.sos = scipy.signal.butter(4, self.fc, fs=fs, output="sos")
        self.mem = memory(self.sos, fs, self.fc)
        self.nd = max(1, int(np.floor(fs / (2.0 * self.fc))))
        impulse = np.zeros(4 * self.mem + 1)
        impulse[2 * self.mem] = 1.0
        h = zero_phase(self.sos, impulse, self.mem)
        g1, _ = central(h, fs)
        self.v_noise = np.sqrt(self.floor_q * fs / 2.0 * np.sum(g1[1:-1] ** 2))
        self.threshold = 3.0 * self.v_noise
        # the half-width holding 99 % of the zero-phase impulse response's absolute sum
        c = 2 * self.mem
        total = np.abs(h).sum()
        inside = abs(h[c])
        self.spread = 2 * self.mem
        for w in range(1, 2 * self.mem):
            if inside >= 0.99 * total:
                self.spread = w - 1
                break
            inside += abs(h[c - w]) + abs(h[c + w])

    def equations(self, q, tau):
        held = tau.copy()
        held[1:] = 0.5 * (tau[1:] + tau[:-1])
        qf = zero_phase(self.sos, q, self.mem)
        qd, qdd = central(qf, self.fs)
        tf = zero_phase(self.sos, held, self.mem)
        sf = zero_phase(self.sos, np.sign(qd), self.mem)
        bad = np.abs(qd) <= self.threshold
        if bad.any():
            bad = np.convolve(bad.astype(float), np.ones(2 * self.spread + 1), "same") > 0.5
        idx = np.arange(self.mem, len(q) - self.mem, self.nd)
        idx = idx[~bad[idx]]
        x = np.column_stack([qdd[idx], qd[idx], sf[idx], np.ones(len(idx))])
        return x, tf[idx]


def main():
    fs = 1000.0
    q, tau = load(sys.argv[1])
    p = Processing(q, tau, fs)
    x, y = p.equations(q, tau)
    theta, *_ = np.linalg.lstsq(x, y, rcond=None)
    r = y - x @ theta
    n, k = x.shape
    cov = (r @ r) / (n - k) * np.linalg.inv(x.T @ x)
    sv = np.linalg.svd(x, compute_uv=False)
    names = ["inertia_kgm2", "viscous_nms_per_rad", "coulomb_nm", "offset_nm"]
    out = {
        "cutoff_hz": p.fc,
        "decimation": p.nd,
        "edge_samples": p.mem,
        "spread_samples": p.spread,
        "velocity_threshold_rad_s": p.threshold,
        "samples_used": n,
        "params": {m: {"value": float(t), "std": float(np.sqrt(c))}
                   for m, t, c in zip(names, theta, np.diag(cov))},
        "condition_number": float(sv[0] / sv[-1]),
        "relative_error_pct": float(100.0 * np.linalg.norm(r) / np.linalg.norm(y)),
    }
    if len(sys.argv) > 2:
        q2, tau2 = load(sys.argv[2])
        x2, y2 = p.equations(q2, tau2)
        out["cross_test_relative_error_pct"] = float(
            100.0 * np.linalg.norm(y2 - x2 @ theta) / np.linalg.norm(y2))
    print(json.dumps(out))


if __name__ == "__main__":
    main()
