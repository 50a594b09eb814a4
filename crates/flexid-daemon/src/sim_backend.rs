//! A simulated [`AxisBackend`]: the plan's torque drives a chain (exact ZOH state space,
//! torque noise, encoder quantisation; or, for a plant file with an `[effects]` section,
//! [`flexid_core::plant::PlantSim`] with every effect) on a thread of its own, in real time
//! (`clock = "monotonic"`) or as fast as possible (`clock = "simulated"`), with the same
//! events, limits and abort behaviour the drive backend has.

use super::backend::{
    AbortSignal, AxisBackend, BackendError, Counters, Outcome, SampleBlock, SweepEvent,
    SweepHandle, SweepPlan,
};
use super::config::{AxisConfig, ClockKind};
use flexid_core::frf::{differenced_velocity_into, FrfKind, PeriodicEstimator};
use flexid_core::model::{Chain, StateSpace};
use flexid_core::plant::PlantSim;
use flexid_files::recording::{Recording, Sidecar};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

/// Time over which an aborted sweep ramps its torque to zero [s].
pub const ABORT_RAMP_S: f64 = 0.05;

/// The simulated backend: every axis is the same chain.
#[derive(Debug, Clone)]
pub struct SimBackend {
    chain: Chain,
    /// RMS of a white disturbance torque [N m].
    pub torque_noise_nm: f64,
    /// Encoder resolution [counts/rev]; `None` for an ideal encoder.
    pub encoder_counts_per_rev: Option<u64>,
    /// Name of the plant, for the sidecar's `source`.
    pub name: String,
    /// The plant with its unmodelled effects (noise and encoder folded in) and the RK4
    /// sub-steps per cycle: simulated by [`flexid_core::plant::PlantSim`] instead of the exact
    /// linear chain. `None`: the linear chain.
    pub effects: Option<(flexid_core::plant::PlantSpec, u32)>,
}

impl SimBackend {
    /// A backend simulating `chain` (validated) with an ideal encoder and no noise.
    pub fn new(chain: Chain, name: &str) -> Result<Self, BackendError> {
        chain.validate().map_err(|e| BackendError::Unavailable {
            axis: "*".into(),
            reason: format!("simulated plant: {e}"),
        })?;
        Ok(SimBackend {
            chain,
            torque_noise_nm: 0.0,
            encoder_counts_per_rev: None,
            name: name.into(),
            effects: None,
        })
    }

    /// A backend for a plant file (the embedded SCARA shoulder when `None`), with its
    /// torque noise and encoder.
    pub fn from_plant_file(path: Option<&std::path::Path>) -> Result<Self, String> {
        let p = flexid_files::plant::load_plant_file(path)?;
        let mut b = SimBackend::new(p.chain.clone(), p.name.as_deref().unwrap_or("plant file"))
            .map_err(|e| e.to_string())?;
        b.torque_noise_nm = p.measurement.torque_noise_nm;
        b.encoder_counts_per_rev = p.measurement.encoder_counts_per_rev;
        if p.has_effects() {
            b.effects = Some((p.spec(), p.substeps()));
        }
        Ok(b)
    }
}

impl AxisBackend for SimBackend {
    fn start(&self, axis: &AxisConfig, plan: SweepPlan) -> Result<SweepHandle, BackendError> {
        if (plan.sample_rate_hz - axis.cycle_hz).abs() > 1e-9 * axis.cycle_hz {
            return Err(BackendError::Plan {
                axis: axis.name.clone(),
                reason: format!(
                    "planned at {} Hz, the axis cycles at {} Hz",
                    plan.sample_rate_hz, axis.cycle_hz
                ),
            });
        }
        let est = PeriodicEstimator::new(
            plan.info.period_samples,
            &plan.info.excited_lines,
            plan.sample_rate_hz,
            FrfKind::DifferencedVelocity,
        )
        .map_err(|e| BackendError::Plan {
            axis: axis.name.clone(),
            reason: e.to_string(),
        })?
        .with_transient_periods(plan.info.transient_periods);
        let nonlinear = match &self.effects {
            None => None,
            Some((spec, substeps)) => Some(Box::new(
                PlantSim::new(spec, plan.sample_rate_hz, *substeps, 0x5eed).map_err(|e| {
                    BackendError::Plan {
                        axis: axis.name.clone(),
                        reason: format!("simulated plant: {e}"),
                    }
                })?,
            )),
        };
        let (tx, rx) = mpsc::channel(256);
        let abort = AbortSignal::default();
        let run = Run {
            sim: self.clone(),
            axis: axis.clone(),
            plan,
            abort: abort.clone(),
            tx,
            est,
            nonlinear,
        };
        std::thread::Builder::new()
            .name(format!("sim-{}", axis.name))
            .spawn(move || run.run())
            .map_err(|e| BackendError::Unavailable {
                axis: axis.name.clone(),
                reason: format!("cannot start the cycle thread: {e}"),
            })?;
        Ok(SweepHandle { events: rx, abort })
    }
}

struct Run {
    sim: SimBackend,
    axis: AxisConfig,
    plan: SweepPlan,
    abort: AbortSignal,
    tx: mpsc::Sender<SweepEvent>,
    est: PeriodicEstimator,
    /// The plant with effects, when the plant file has any (else the linear chain).
    nonlinear: Option<Box<PlantSim>>,
}

impl Run {
    fn run(mut self) {
        let fs = self.plan.sample_rate_hz;
        let ts = 1.0 / fs;
        let n = self.sim.chain.masses();
        let d = StateSpace::of(&self.sim.chain).discretize(ts);
        let mut x = vec![0.0; 2 * n];
        let mut next = vec![0.0; 2 * n];
        let mut rng = rand::rngs::StdRng::seed_from_u64(0x5eed);
        let unit = Normal::new(0.0, 1.0).ok();
        let quantum = self
            .sim
            .encoder_counts_per_rev
            .map(|c| 2.0 * std::f64::consts::PI / c as f64);
        let period = self.plan.info.period_samples.max(1);
        let total = self.plan.torque_nm.len();
        let lim = self.axis.limits.clone();
        let mut rec_t = Vec::with_capacity(total);
        let mut rec_u = Vec::with_capacity(total);
        let mut rec_p = Vec::with_capacity(total);
        let mut vel = vec![0.0; period];
        let mut prev_pos = None;
        let mut counters = Counters::default();
        let t0 = Instant::now();
        let mut block_start = 0usize;
        let mut stop: Option<(Outcome, String)> = None;
        let mut ramp: Option<(usize, f64)> = None; // (samples left, torque at the start)
        let ramp_len = ((ABORT_RAMP_S * fs).ceil() as usize).max(1);
        let mut k = 0usize;
        let realtime = self.axis.clock == ClockKind::Monotonic;
        loop {
            // torque of this cycle
            let u = if let Some((left, from)) = ramp {
                if left == 0 {
                    break;
                }
                ramp = Some((left - 1, from));
                from * (left - 1) as f64 / ramp_len as f64
            } else if k >= total {
                break;
            } else {
                if self.abort.is_aborted() {
                    let reason = self.abort.reason().unwrap_or_else(|| "abort".into());
                    stop = Some((Outcome::Aborted, reason));
                    let from = rec_u.last().copied().unwrap_or(0.0);
                    ramp = Some((ramp_len, from));
                    continue;
                }
                self.plan.torque_nm[k]
            };
            // sample, then apply the torque over the cycle (ZOH)
            let p = match &self.nonlinear {
                Some(sim) => sim.sample().position_rad,
                None => match quantum {
                    Some(q) => (x[0] / q).round() * q,
                    None => x[0],
                },
            };
            rec_t.push(k as f64 * ts);
            rec_u.push(u);
            rec_p.push(p);
            if let Some(sim) = self.nonlinear.as_mut() {
                sim.step(u);
                x[0] = sim.body_positions()[0];
                x[n] = sim.body_velocities()[0];
            } else {
                let mut ua = u;
                if self.sim.torque_noise_nm > 0.0 {
                    if let Some(unit) = &unit {
                        ua += self.sim.torque_noise_nm * unit.sample(&mut rng);
                    }
                }
                for (i, nx) in next.iter_mut().enumerate() {
                    let mut acc = d.bd[i] * ua;
                    for (j, xj) in x.iter().enumerate() {
                        acc += d.ad[(i, j)] * xj;
                    }
                    *nx = acc;
                }
                std::mem::swap(&mut x, &mut next);
            }
            counters.cycles += 1;
            k += 1;
            if stop.is_none() {
                let speed = x[n].abs();
                if !speed.is_finite() || speed > lim.max_speed_rad_s {
                    stop = Some((
                        Outcome::Failed,
                        format!(
                            "speed limit: {speed:.3} rad/s above {} rad/s",
                            lim.max_speed_rad_s
                        ),
                    ));
                } else if x[0].abs() > lim.position_window_rad {
                    stop = Some((
                        Outcome::Failed,
                        format!(
                            "position window: {:.4} rad beyond +-{} rad",
                            x[0], lim.position_window_rad
                        ),
                    ));
                }
                if stop.is_some() {
                    ramp = Some((ramp_len, u));
                }
            }
            // a completed period (or the end of a stopped sweep): report it
            let at_end = ramp.is_some_and(|r| r.0 == 0) || (ramp.is_none() && k >= total);
            if k - block_start == period || (at_end && k > block_start) {
                if realtime {
                    let due = t0 + Duration::from_secs_f64(k as f64 * ts);
                    let now = Instant::now();
                    if due > now {
                        std::thread::sleep(due - now);
                    }
                }
                counters.period_end_mono_ns = flexid_rt::clock::now_ns();
                if !self.report(
                    block_start,
                    k,
                    &rec_u,
                    &rec_p,
                    &mut vel,
                    &mut prev_pos,
                    counters,
                ) {
                    return; // nobody listens any more
                }
                block_start = k;
            }
        }
        let (outcome, reason) = stop.unwrap_or((Outcome::Completed, "completed".into()));
        let sidecar = Sidecar {
            sample_rate_hz: Some(fs),
            excitation: Some(self.plan.info.clone()),
            total_inertia_kgm2: None,
            io_delay_samples: Some(0),
            source: Some(format!("simulated: {} (daemon sim backend)", self.sim.name)),
            ended_because: (outcome != Outcome::Completed).then(|| reason.clone()),
            end: Some(flexid_files::recording::RecordingEnd {
                complete: outcome == Outcome::Completed,
                reason: reason.clone(),
                cycle: counters.cycles,
            }),
            cycle_counters: Some(flexid_files::recording::CycleCounters {
                cycles: counters.cycles,
                ..Default::default()
            }),
            drive: None,
            cycle_timing: None,
        };
        let recording = Recording {
            time_s: rec_t,
            torque_cmd_nm: rec_u,
            position_rad: Some(rec_p),
            velocity_rad_s: None,
            acceleration_rad_s2: None,
            torque_actual_nm: None,
            sample_rate_hz: fs,
            sidecar,
        };
        let _ = self.tx.blocking_send(SweepEvent::Ended {
            outcome,
            reason,
            recording: Some(recording),
        });
    }

    #[allow(clippy::too_many_arguments)]
    fn report(
        &mut self,
        from: usize,
        to: usize,
        u: &[f64],
        p: &[f64],
        vel: &mut Vec<f64>,
        prev_pos: &mut Option<f64>,
        counters: Counters,
    ) -> bool {
        let index = from / self.plan.info.period_samples.max(1);
        let full = to - from == self.plan.info.period_samples;
        let mut frf_so_far = None;
        if full {
            vel.resize(to - from, 0.0);
            *prev_pos =
                differenced_velocity_into(&p[from..to], self.plan.sample_rate_hz, *prev_pos, vel);
            if self.est.push(&u[from..to], vel).is_ok() && self.est.periods_done() > 0 {
                frf_so_far = self.est.estimate().ok().map(Arc::new);
            }
        }
        let ev = SweepEvent::Period {
            index,
            samples: SampleBlock {
                first_sample: from,
                torque_cmd_nm: u[from..to].to_vec(),
                position_rad: p[from..to].to_vec(),
            },
            frf_so_far,
            elapsed_s: to as f64 / self.plan.sample_rate_hz,
            counters,
        };
        self.tx.blocking_send(ev).is_ok()
    }
}
