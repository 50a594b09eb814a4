//! The world's fine-step simulator, written for the benchmark alone (it shares no code
//! with `flexid::plant`, `flexid::sim` or the diagnosis's `nlsim`): the torque command held
//! over each sample (ZOH) and delayed by any fraction of a sample, the drive's filters, the
//! bodies, couplings and ground forces of a [`Plant`] and the sensor path, all in one state
//! vector integrated by the classical fourth-order Runge-Kutta method on fixed sub-steps.
//!
//! Sub-steps per sample ([`super::substeps`]) follow from the stiffest dynamics: the highest
//! eigenfrequency of the bodies with every spring at the largest stiffness it reaches
//! (hardening at the expected peak deflection, backlash in contact, gravity, cogging, the
//! ground spring at its peak travel), the filters' and sensor's own frequencies, and the
//! fastest damping rate (dampers, the friction's regularisation). The step keeps
//! `w_max h <= 0.1` and `rate h <= 0.2`: RK4's relative frequency error on an oscillator
//! is about `(w h)^4 / 120`, 8e-7 there, which near a resonance of damping ratio `z`
//! becomes a relative FRF error of about that over `z` (2e-4 at 0.5 %), below the line
//! noise of the best-measured lines (at `w h <= 0.2` it was 16x larger, 1e-4 on a 3 %
//! resonance: `tests/diagnose_world.rs`); the rate bound keeps the friction's steep but
//! smooth passage through zero speed resolved (1e-4 of the RMS velocity at most, 1e-3 at
//! `rate h <= 0.5`). A step across a kink of the forces (a backlash's flank, the
//! amplifier's dead zone) is cut at the kink: without that, backlash converged at first
//! order and left 26 % (max over a record) at the derived step, with it 7e-4.
//!
//! Sampling follows a drive's cycle: at sample `k` the outputs are read, then the command
//! `u[k]` is held over `[k T, (k + 1) T)` (after the delay).

use super::plant::{Law, LowPass, Output, Plant};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// The outputs of one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// The measured position (after the sensor path, quantised unless exact) [rad].
    pub position_rad: f64,
    /// The drive's velocity reading [rad/s] (see [`Output::Velocity`]).
    pub velocity_rad_s: f64,
    /// The drive's reading of the motor's torque (current) [N m].
    pub torque_actual_nm: f64,
}

/// Where each part lives in the state vector.
#[derive(Debug, Clone, Copy)]
struct Layout {
    bodies: usize,
    notch: usize,
    current_loop: usize,
    shaft: usize,
    lowpass: usize,
    len: usize,
}

impl Layout {
    fn of(p: &Plant) -> Layout {
        let bodies = p.bodies();
        let mut at = 2 * bodies;
        let mut take = |n: usize| {
            let i = at;
            at += n;
            i
        };
        let notch = take(if p.drive.notch.is_some() { 2 } else { 0 });
        let current_loop = take(p.drive.current_loop.map_or(0, |l| l.order as usize));
        let shaft = take(if p.sensor.shaft.is_some() { 2 } else { 0 });
        let lowpass = take(p.sensor.lowpass.map_or(0, |l| l.order as usize));
        Layout {
            bodies,
            notch,
            current_loop,
            shaft,
            lowpass,
            len: at,
        }
    }
}

fn rad_s(hz: f64) -> f64 {
    2.0 * std::f64::consts::PI * hz
}

/// A low-pass's derivative at `x[i..]` with input `u`; returns its output.
fn lowpass_deriv(l: &LowPass, x: &[f64], i: usize, u: f64, dx: &mut [f64]) -> f64 {
    let w = rad_s(l.bandwidth_hz);
    if l.order == 1 {
        dx[i] = w * (u - x[i]);
    } else {
        dx[i] = x[i + 1];
        dx[i + 1] = w * w * (u - x[i]) - 2.0 * l.damping_ratio * w * x[i + 1];
    }
    x[i]
}

/// The torque of coupling `c` at deflection `x` [rad] and deflection rate `v` [rad/s].
fn coupling_torque(c: &super::plant::Coupling, x: f64, v: f64) -> f64 {
    let (k, d) = (c.stiffness_nm_per_rad, c.damping_nms_per_rad);
    match c.law {
        Law::Linear => k * x + d * v,
        Law::Hardening { x_ref_rad } => k * x * (1.0 + (x / x_ref_rad).powi(2)) + d * v,
        Law::DeadZone {
            half_gap_rad,
            contact_ramp_rad,
        } => {
            let pen = x.abs() - half_gap_rad;
            if pen <= 0.0 {
                0.0
            } else {
                let ramp = (pen / contact_ramp_rad).min(1.0);
                k * pen * x.signum() + d * v * ramp
            }
        }
    }
}

/// The drive's torque on the motor for command `u` in state `x` (after the filters and the
/// dead zone); writes the state derivative of the whole plant with disturbance `w`.
fn deriv(p: &Plant, l: &Layout, x: &[f64], u: f64, w: f64, dx: &mut [f64]) -> f64 {
    let nb = l.bodies;
    // the torque path
    let mut t = u;
    if let Some(n) = &p.drive.notch {
        let wn = rad_s(n.centre_hz);
        let (x1, x2) = (x[l.notch], x[l.notch + 1]);
        dx[l.notch] = x2;
        dx[l.notch + 1] = -wn * wn * x1 - 2.0 * n.pole_damping_ratio * wn * x2 + t;
        t += 2.0 * (n.zero_damping_ratio - n.pole_damping_ratio) * wn * x2;
    }
    if let Some(cl) = &p.drive.current_loop {
        t = lowpass_deriv(cl, x, l.current_loop, t, dx);
    }
    let dz = p.drive.dead_zone_nm;
    if dz > 0.0 {
        t = t.signum() * (t.abs() - dz).max(0.0);
    }
    let applied = t;
    // the bodies
    for i in 0..nb {
        dx[i] = x[nb + i];
        dx[nb + i] = 0.0;
    }
    let (q0, v0) = (x[0], x[nb]);
    let mut m = applied + w - p.motor_viscous_nms_per_rad * v0;
    if let Some(f) = &p.friction {
        let level =
            f.coulomb_nm + (f.static_nm - f.coulomb_nm) * (-(v0 / f.stribeck_rad_s).powi(2)).exp();
        m -= level * (v0 / f.regularisation_rad_s).tanh();
    }
    if let Some(c) = &p.cogging {
        m -= c.amplitude_nm * (c.periods_per_rev * q0).sin();
    }
    dx[nb] = m;
    for (k, c) in p.couplings.iter().enumerate() {
        let t = coupling_torque(c, x[k + 1] - x[k], x[nb + k + 1] - x[nb + k]);
        dx[nb + k] += t;
        dx[nb + k + 1] -= t;
    }
    if let Some(g) = &p.gravity {
        let b = g.body;
        dx[nb + b] -= g.m_g_l_nm * x[b].sin() + g.bearing_damping_nms_per_rad * x[nb + b];
    }
    if let Some(g) = &p.ground_cubic {
        dx[nb + g.body] -= g.cubic_nm_per_rad3 * x[g.body].powi(3);
    }
    for i in 0..nb {
        dx[nb + i] /= p.inertia_kgm2[i];
    }
    let (mut raw, raw_dot) = (q0, v0);
    // the sensor path
    if let Some(s) = &p.sensor.shaft {
        let we = rad_s(s.frequency_hz);
        let (th, om) = (x[l.shaft], x[l.shaft + 1]);
        dx[l.shaft] = om;
        dx[l.shaft + 1] = we * we * (raw - th) + 2.0 * s.damping_ratio * we * (raw_dot - om);
        raw = th;
    }
    if let Some(lp) = &p.sensor.lowpass {
        lowpass_deriv(lp, x, l.lowpass, raw, dx);
    }
    applied
}

/// One RK4 step of `h` from `x` into `out`.
#[allow(clippy::too_many_arguments)]
fn rk4(
    p: &Plant,
    l: &Layout,
    x: &[f64],
    h: f64,
    u: f64,
    w: f64,
    k: &mut [Vec<f64>; 4],
    tmp: &mut [f64],
    out: &mut [f64],
) {
    let [k1, k2, k3, k4] = k;
    deriv(p, l, x, u, w, k1);
    for i in 0..x.len() {
        tmp[i] = x[i] + 0.5 * h * k1[i];
    }
    deriv(p, l, tmp, u, w, k2);
    for i in 0..x.len() {
        tmp[i] = x[i] + 0.5 * h * k2[i];
    }
    deriv(p, l, tmp, u, w, k3);
    for i in 0..x.len() {
        tmp[i] = x[i] + h * k3[i];
    }
    deriv(p, l, tmp, u, w, k4);
    for i in 0..x.len() {
        out[i] = x[i] + h / 6.0 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
    }
}

/// The torque reference after the notch and the current loop, before the dead zone.
fn torque_before_dead_zone(p: &Plant, l: &Layout, x: &[f64], u: f64) -> f64 {
    if p.drive.current_loop.is_some() {
        return x[l.current_loop];
    }
    match &p.drive.notch {
        Some(n) => {
            u + 2.0
                * (n.zero_damping_ratio - n.pole_damping_ratio)
                * rad_s(n.centre_hz)
                * x[l.notch + 1]
        }
        None => u,
    }
}

/// The kinks of the forces as functions of the state, each changing sign where a force's
/// slope jumps: a backlash's flank touched (`|x| - g`) and its contact damping fully
/// engaged (`|x| - g - ramp`), the amplifier's dead zone left (`|T| - d`); and where the
/// motor reverses when the encoder has play (the disc then stays behind), so that the
/// play is taken up at the true turning point.
fn kinks(p: &Plant, l: &Layout, x: &[f64], u: f64, out: &mut Vec<f64>) {
    out.clear();
    for (k, c) in p.couplings.iter().enumerate() {
        if let Law::DeadZone {
            half_gap_rad,
            contact_ramp_rad,
        } = c.law
        {
            let d = (x[k + 1] - x[k]).abs();
            out.push(d - half_gap_rad);
            out.push(d - half_gap_rad - contact_ramp_rad);
        }
    }
    if p.drive.dead_zone_nm > 0.0 {
        out.push(torque_before_dead_zone(p, l, x, u).abs() - p.drive.dead_zone_nm);
    }
    if p.sensor.half_play_rad > 0.0 {
        // the reading reverses (the disc is left behind): its rate through zero
        out.push(if p.sensor.lowpass.is_some() || p.sensor.shaft.is_some() {
            0.0
        } else {
            x[l.bodies]
        });
    }
}

/// The encoder's reading of state `x` before any play: after the position low-pass, or
/// the disc on its compliant shaft, or the motor's angle.
fn reading(p: &Plant, l: &Layout, x: &[f64]) -> f64 {
    if p.sensor.lowpass.is_some() {
        x[l.lowpass]
    } else if p.sensor.shaft.is_some() {
        x[l.shaft]
    } else {
        x[0]
    }
}

/// The fine-step simulation of one plant at one sample rate.
pub struct Sim {
    plant: Plant,
    layout: Layout,
    ts: f64,
    substeps: usize,
    delay_whole: usize,
    delay_frac: f64,
    exact: bool,
    x: Vec<f64>,
    k: [Vec<f64>; 4],
    tmp: Vec<f64>,
    trial: Vec<f64>,
    g0: Vec<f64>,
    g1: Vec<f64>,
    /// The last commands, a ring of `delay_whole + 2`.
    commands: Vec<f64>,
    cycle: usize,
    last_command: f64,
    /// The encoder disc's angle when it sits on the shaft with play.
    disc: f64,
    rng: rand::rngs::StdRng,
}

impl Sim {
    /// A simulation at rest with `substeps` RK4 steps per sample. `exact`: no disturbance,
    /// no quantisation, no current noise (for sizing effects and checking the simulator);
    /// otherwise the noise is drawn from `seed`.
    pub fn new(plant: &Plant, fs_hz: f64, substeps: usize, seed: u64, exact: bool) -> Sim {
        let layout = Layout::of(plant);
        let ts = 1.0 / fs_hz;
        let d = plant.drive.delay_s / ts;
        let delay_whole = d.floor() as usize;
        Sim {
            plant: plant.clone(),
            layout,
            ts,
            substeps: substeps.max(1),
            delay_whole,
            delay_frac: d - d.floor(),
            exact,
            x: vec![0.0; layout.len],
            k: std::array::from_fn(|_| vec![0.0; layout.len]),
            tmp: vec![0.0; layout.len],
            trial: vec![0.0; layout.len],
            g0: Vec::new(),
            g1: Vec::new(),
            commands: vec![0.0; delay_whole + 2],
            cycle: 0,
            last_command: 0.0,
            disc: 0.0,
            rng: rand::rngs::StdRng::seed_from_u64(seed),
        }
    }

    /// Start the rigid-body motion centred on `u` (one period of a periodic command, or a
    /// whole record): every body's initial velocity and position set so that a free axis
    /// under `u` neither drifts nor sits off zero on average (as a position loop of a low
    /// bandwidth would keep a real axis). Position-dependent forces (a cubic ground spring,
    /// cogging, gravity) then act around their rest position, not around wherever an
    /// uncentred start would carry the axis. An arm under gravity is not free: it hangs,
    /// and starts at rest where it hangs (a free body's centring velocity would throw it
    /// into a swing of its own, over the top on a slow sine).
    pub fn start_centred(&mut self, u: &[f64]) {
        if self.plant.gravity.is_some() {
            return;
        }
        let jt = self.plant.total_inertia_kgm2();
        let ts = self.ts;
        // velocity and position of a free rigid body from rest, per sample
        let (mut v, mut q) = (0.0, 0.0);
        let (mut sv, mut sq) = (0.0, 0.0);
        for &t in u {
            sv += v;
            sq += q;
            let a = t / jt;
            q += v * ts + 0.5 * a * ts * ts;
            v += a * ts;
        }
        let n = u.len().max(1) as f64;
        let v0 = -sv / n;
        // the position with v0 added: q_k + v0 k ts, its mean over k = 0 .. n-1
        let q0 = -(sq / n + v0 * ts * (n - 1.0) / 2.0);
        let nb = self.layout.bodies;
        for i in 0..nb {
            self.x[i] = q0;
            self.x[nb + i] = v0;
        }
        self.disc = reading(&self.plant, &self.layout, &self.x);
    }

    /// The measured position before quantisation.
    fn measured(&self) -> f64 {
        if self.plant.sensor.half_play_rad > 0.0 {
            self.disc
        } else {
            reading(&self.plant, &self.layout, &self.x)
        }
    }

    /// Integrate `duration` seconds with command `u` and disturbance `w` on `n` RK4 steps.
    /// A step across a kink of the forces ([`kinks`]) is cut at the kink (located by
    /// bisection to 1e-6 of the step) and continued from there, so that RK4 keeps its
    /// order on piecewise smooth forces.
    fn integrate(&mut self, u: f64, w: f64, duration: f64, n: usize) {
        let h = duration / n as f64;
        let Sim {
            plant,
            layout,
            x,
            k,
            tmp,
            trial,
            g0,
            g1,
            disc,
            ..
        } = self;
        let play = plant.sensor.half_play_rad;
        // the disc is pushed by the shaft's reading only where the play is taken up
        let carry = |x: &[f64], disc: &mut f64| {
            if play > 0.0 {
                let r = reading(plant, layout, x);
                *disc = disc.clamp(r - play, r + play);
            }
        };
        let crossed = |a: &[f64], b: &[f64]| a.iter().zip(b).any(|(a, b)| (*a > 0.0) != (*b > 0.0));
        for _ in 0..n {
            let mut left = h;
            for _cut in 0..8 {
                kinks(plant, layout, x, u, g0);
                rk4(plant, layout, x, left, u, w, k, tmp, trial);
                kinks(plant, layout, trial, u, g1);
                if !crossed(g0, g1) {
                    x.copy_from_slice(trial);
                    carry(x, disc);
                    left = 0.0;
                    break;
                }
                // the earliest crossing: bisect the fraction of the step
                let (mut lo, mut hi) = (0.0, 1.0);
                for _ in 0..20 {
                    let mid = 0.5 * (lo + hi);
                    rk4(plant, layout, x, mid * left, u, w, k, tmp, trial);
                    kinks(plant, layout, trial, u, g1);
                    if crossed(g0, g1) {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
                rk4(plant, layout, x, hi * left, u, w, k, tmp, trial);
                x.copy_from_slice(trial);
                carry(x, disc);
                left -= hi * left;
            }
            if left > 0.0 {
                // more kinks in one step than cuts allowed: the rest in one step
                rk4(plant, layout, x, left, u, w, k, tmp, trial);
                x.copy_from_slice(trial);
                carry(x, disc);
            }
        }
    }

    /// Read the outputs of this sample, then advance one sample with command `u`.
    pub fn step(&mut self, u: f64) -> Sample {
        let count = self.plant.sensor.count_rad();
        let mut pos = self.measured();
        let nb = self.layout.bodies;
        let mut vel = self.x[nb];
        // the drive's current reading: the torque of the command in effect until now
        let mut tq = deriv(
            &self.plant,
            &self.layout,
            &self.x,
            self.last_command,
            0.0,
            &mut self.tmp,
        );
        let w = if self.exact {
            0.0
        } else {
            pos = (pos / count).floor() * count;
            if self.plant.sensor.output == Output::Velocity {
                let sd = count / self.ts / 6f64.sqrt();
                vel += normal(&mut self.rng, sd);
            }
            tq += normal(&mut self.rng, self.plant.sensor.current_noise_nm);
            normal(&mut self.rng, self.plant.torque_noise_nm)
        };
        // u[k - m - 1] until the fractional part of the delay has passed, u[k - m] after
        let len = self.commands.len();
        self.commands[self.cycle % len] = u;
        let m = self.delay_whole;
        let at = |lag: usize| {
            if self.cycle >= lag {
                self.commands[(self.cycle - lag) % len]
            } else {
                0.0
            }
        };
        let (early, late) = (at(m + 1), at(m));
        let f = self.delay_frac;
        if f > 1e-12 {
            let n0 = ((self.substeps as f64 * f).ceil() as usize).max(1);
            let n1 = ((self.substeps as f64 * (1.0 - f)).ceil() as usize).max(1);
            self.integrate(early, w, f * self.ts, n0);
            self.integrate(late, w, (1.0 - f) * self.ts, n1);
        } else {
            self.integrate(late, w, self.ts, self.substeps);
        }
        self.last_command = late;
        self.cycle += 1;
        Sample {
            position_rad: pos,
            velocity_rad_s: vel,
            torque_actual_nm: tq,
        }
    }

    /// Run a whole command sequence.
    pub fn run(&mut self, u: &[f64]) -> Vec<Sample> {
        u.iter().map(|&t| self.step(t)).collect()
    }
}

fn normal(rng: &mut rand::rngs::StdRng, sd: f64) -> f64 {
    if sd > 0.0 {
        Normal::new(0.0, sd).unwrap().sample(rng)
    } else {
        0.0
    }
}
