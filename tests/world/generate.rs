//! The generation of one case from its seed alone: the world drawn (plant, measurement),
//! every effect or cause sized and applied, the recordings simulated with noise and
//! written with their sidecars, and `truth.json`.
//!
//! Every case draws its own world: 2, 3 or 4 bodies (4 in `four_masses`), 2 or 4 kHz,
//! 0.5 or 1 Hz lines, an excitation kind, an encoder of 14-22 bits, a disturbance torque
//! of 0.1-1 % of the low level's RMS (x1, or x3 in half the cases), viscous friction to the
//! ground in two thirds of the axes, two levels 3-5x apart whose high one moves the motor at
//! 0.3-3 rad/s RMS. An effect's or cause's full size is a typical one drawn from its
//! physical range (see [`super::effects`], [`super::causes`]), enlarged where needed until
//! its visibility beyond the nominal model ([`super::visibility`]: the RMS of the change
//! no re-fitted nominal chain absorbs, in units of the line noise) reaches a target drawn
//! log-uniform in 4 .. 10: clearly visible in every case. Group B applies a third of the
//! full size.

use super::analytic;
use super::cases::{Case, Group, Measurement, Sizing, Spec, Truth};
use super::causes::cause;
use super::effects::{effect, Context, Knob};
use super::excitation::{Design, Kind, KINDS};
use super::plant::{Output, Plant};
use super::plants::{motor_viscous, random_chain};
use super::simulator::Sim;
use super::substeps::{substeps, Peaks};
use super::visibility::{
    acting_band, delta_linear, delta_of, detectable, ln_h1_lines, measured_sigma_ln,
    measured_sigma_stepped, repeated_sigma_ln, sigma_ln, simulated_response, size_for, visibility,
    Projector, Reference, Stepped,
};
use flexid::model::Chain;
use flexid::recording::{write_recording, Recording, Sidecar};
use flexid::Complex64;
use rand::{Rng, SeedableRng};
use std::path::Path;

fn log_uniform(rng: &mut impl Rng, lo: f64, hi: f64) -> f64 {
    rng.random_range(lo.ln()..hi.ln()).exp()
}

/// The world of a case before any effect: plant, measurement and sizing context.
struct World {
    plant: Plant,
    chain: Chain,
    viscous: f64,
    design: Design,
    ctx: Context,
    noise_factor: f64,
}

/// `level_scale` multiplies both levels and the noise drawn against them (1 but where a
/// swinging arm must be kept in its linear range, [`gravity_level_scale`]).
fn draw_world(spec: &Spec, rng: &mut impl Rng, level_scale: f64) -> World {
    let var = if spec.group == Group::E {
        spec.class
    } else {
        ""
    };
    let fs = spec.fs_hz.unwrap_or(if var == "fs_4khz" {
        4000.0
    } else {
        [2000.0, 4000.0][rng.random_range(0..2usize)]
    });
    let n = if var == "four_masses" {
        4
    } else {
        rng.random_range(2..=4usize)
    };
    let df = [0.5, 1.0][rng.random_range(0..2usize)];
    let f_lo = df * rng.random_range(1..=2u32) as f64;
    let band = [f_lo, 0.4 * fs];
    let chain = random_chain(rng, n, (6.0 * df).max(3.0), 0.3 * fs, 4.0 * df);
    let viscous = if var == "no_viscous" {
        0.0
    } else {
        motor_viscous(rng, &chain)
    };
    let kind = match var {
        "schroeder" => Kind::Schroeder,
        "random_phase" => Kind::RandomPhase,
        "swept_sine" => Kind::SweptSine,
        "stepped_sine" => Kind::SteppedSine,
        _ => KINDS[rng.random_range(0..KINDS.len())],
    };
    let design = Design {
        kind,
        fs_hz: fs,
        line_spacing_hz: df,
        band_hz: band,
        periods: 5,
        transient_periods: 2,
        phase_seed: rng.random(),
        odd_group: rng.random_range(3..=4usize),
        stepped_spots: 40,
    };
    let bits = if var == "encoder_14bit" {
        14
    } else {
        rng.random_range(14..=22u32)
    };
    let noise_factor = if var == "noise_x3" || rng.random_bool(0.5) {
        3.0
    } else {
        1.0
    };
    let mut plant = Plant::nominal(&chain, viscous, bits);
    if var == "velocity_output" {
        plant.sensor.output = Output::Velocity;
    }
    // levels: the high one moves the motor at 0.3-3 rad/s RMS, the low one 3-5x below
    let grid = design.grid_hz();
    let v_high = log_uniform(rng, 0.3, 3.0);
    let rms_high = level_scale * v_high / analytic::rms_velocity(&plant, &grid, 1.0);
    let rms_low = rms_high / rng.random_range(3.0..5.0);
    let levels = vec![rms_low, rms_high];
    plant.torque_noise_nm = noise_factor * log_uniform(rng, 1e-3, 1e-2) * rms_low;
    plant.sensor.current_noise_nm = 2e-3 * rms_low;
    let phase_seed = rng.random();
    let own = own_multisine(&design, &levels);
    let stepped = (design.kind == Kind::SteppedSine).then(|| {
        levels
            .iter()
            .map(|&r| {
                let (u, info) = design.generate(r);
                Stepped {
                    u,
                    blocks: info.blocks,
                }
            })
            .collect::<Vec<_>>()
    });
    let lines_hz = match (&own, &stepped) {
        (Some(o), _) => o.0.clone(),
        (None, Some(st)) => st[0].blocks.iter().map(|b| b.frequency_hz).collect(),
        (None, None) => grid.clone(),
    };
    let reference = Reference {
        fs_hz: fs,
        lines_hz,
        period_samples: design.period_samples(),
        periods: design.periods,
        levels_rms_nm: levels.clone(),
        phase_seed,
        own_periods: own.map(|o| o.1),
        energy: (design.kind == Kind::SweptSine).then(|| {
            levels
                .iter()
                .map(|&r| design.line_energy(r, &grid))
                .collect()
        }),
        stepped,
        grid_hz: grid.clone(),
    };
    let motion = levels
        .iter()
        .map(|&r| analytic::rms_motion(&plant, &grid, r))
        .collect();
    let velocity = levels
        .iter()
        .map(|&r| analytic::rms_velocity(&plant, &grid, r))
        .collect();
    let ctx = Context {
        nominal: plant.clone(),
        fs_hz: fs,
        band_hz: band,
        reference,
        motion,
        velocity_rms_rad_s: velocity,
    };
    World {
        plant,
        chain,
        viscous,
        design,
        ctx,
        noise_factor,
    }
}

/// Peaks for the sub-step count: 6x the small-signal RMS at the high level.
pub fn peaks_of(plant: &Plant, ctx: &Context) -> Peaks {
    let r = analytic::rms_motion(
        plant,
        ctx.reference.motion_lines_hz(),
        ctx.reference.levels_rms_nm[ctx.high()],
    );
    Peaks {
        deflection_rad: r.deflection_rad.iter().map(|x| 6.0 * x).collect(),
        position_rad: r.position_rad.iter().map(|x| 6.0 * x).collect(),
    }
}

/// The excited lines [Hz] and one period per level [N m] of `design` when it is a periodic
/// multisine.
fn own_multisine(design: &Design, levels: &[f64]) -> Option<(Vec<f64>, Vec<Vec<f64>>)> {
    if !matches!(
        design.kind,
        Kind::OddRandom | Kind::Schroeder | Kind::RandomPhase
    ) {
        return None;
    }
    let n = design.period_samples();
    let mut lines = Vec::new();
    let periods = levels
        .iter()
        .map(|&rms| {
            let (u, info) = design.generate(rms);
            lines = info
                .excited_lines
                .iter()
                .map(|&k| k as f64 * design.fs_hz / n as f64)
                .collect();
            u[..n].to_vec()
        })
        .collect();
    Some((lines, periods))
}

/// Visibility of `plant` against the nominal axis (simulated unless `linear`), and the
/// change per line and level.
struct Judge<'a> {
    ctx: &'a Context,
    sigma: Vec<Vec<f64>>,
    projector: Projector,
    /// The projector that may also add a drive delay and a spring to the ground: a cause
    /// outside the library is judged beyond the nominal model and what the library's
    /// `time_delay` and `gravity` mimic ([`Projector::with_delay`],
    /// [`Projector::with_ground_spring`]).
    beyond_library: Projector,
    nominal_sim: std::cell::OnceCell<super::visibility::Simulated>,
}

impl<'a> Judge<'a> {
    fn new(ctx: &'a Context) -> Self {
        let sigma = sigma_ln(&ctx.nominal, &ctx.reference);
        Judge {
            ctx,
            projector: Projector::new(&ctx.nominal, &ctx.reference, sigma.clone()),
            beyond_library: Projector::new(&ctx.nominal, &ctx.reference, sigma.clone())
                .with_delay(ctx.fs_hz)
                .with_ground_spring(),
            sigma,
            nominal_sim: std::cell::OnceCell::new(),
        }
    }

    /// `ln(H_with / H_nominal)` per level and line; `None` when the with-effect response
    /// is not periodic ([`super::visibility::Simulated::periodic_like`]).
    fn delta(&self, plant: &Plant, linear: bool) -> Option<Vec<Vec<flexid::Complex64>>> {
        let r = &self.ctx.reference;
        if linear {
            return Some(delta_linear(&self.ctx.nominal, plant, r));
        }
        let nominal = self.nominal_sim.get_or_init(|| {
            simulated_response(&self.ctx.nominal, r, &peaks_of(&self.ctx.nominal, self.ctx))
        });
        let with = simulated_response(plant, r, &peaks_of(plant, self.ctx));
        with.periodic_like(nominal, &self.sigma)
            .then(|| delta_of(&nominal.response, &with.response))
    }

    /// Visibility beyond the nominal model (what no re-fitted nominal chain absorbs; for a
    /// cause `outside` the library, nor what a library delay or ground spring mimics), and
    /// against the true nominal chain; `None` when the response is not periodic.
    /// `starts`: further starts of the refit ([`Judge::residual`]).
    fn visibility(
        &self,
        plant: &Plant,
        linear: bool,
        outside: bool,
        starts: &[Plant],
    ) -> Option<(f64, f64)> {
        self.delta(plant, linear)
            .map(|d| self.visibility_of(&d, outside, starts))
    }

    fn visibility_of(
        &self,
        delta: &[Vec<flexid::Complex64>],
        outside: bool,
        starts: &[Plant],
    ) -> (f64, f64) {
        (
            visibility(&self.residual(delta, outside, starts), &self.sigma),
            visibility(delta, &self.sigma),
        )
    }

    /// What is left of `delta` beyond the nominal model (and, for a cause `outside` the
    /// library, beyond a library delay and ground spring), the refit also started from
    /// each of `starts` (the chains the effects' physics say a nominal model makes of them:
    /// [`super::effects::Knob::absorbed`]).
    fn residual(
        &self,
        delta: &[Vec<flexid::Complex64>],
        outside: bool,
        starts: &[Plant],
    ) -> Vec<Vec<flexid::Complex64>> {
        if outside {
            self.beyond_library.residual_from(delta, starts)
        } else {
            self.projector.residual_from(delta, starts)
        }
    }

    /// The least visibility a diagnosis can be required to see ([`detectable`]).
    fn detectable(&self) -> f64 {
        detectable(&self.sigma)
    }
}

/// The full size of `knob` alone on the nominal axis: a typical size `drawn`, enlarged
/// until its visibility beyond the nominal model reaches `target` where it falls short.
/// Returns the size, its visibility, and the drawn size's visibility.
/// The nominal chain a nominal model makes of `effects` (each knob at its size) as their
/// physics says ([`Knob::absorbed`]): one start for the world's refit, or none where no
/// effect names such a chain.
fn absorbed(nominal: &Plant, effects: &[(&Knob, f64)]) -> Vec<Plant> {
    let mut chain = nominal.clone();
    let mut any = false;
    for (k, size) in effects {
        any |= k.absorbed(&mut chain, *size);
    }
    if any {
        vec![chain]
    } else {
        vec![]
    }
}

fn full_size(knob: &Knob, judge: &Judge, drawn: f64, target: f64) -> (f64, f64, f64) {
    let vis = |s: f64| {
        let mut p = judge.ctx.nominal.clone();
        knob.apply(&mut p, s);
        // a size whose response is not periodic is too large
        judge
            .visibility(
                &p,
                knob.linear,
                knob.answer == "unexplained",
                &absorbed(&judge.ctx.nominal, &[(knob, s)]),
            )
            .map_or(f64::MAX, |v| v.0)
    };
    let v_drawn = vis(drawn);
    if v_drawn == f64::MAX {
        // the drawn size already drives the axis out of a steady state: the largest size
        // below it whose response is periodic, towards the target
        let (s, v) = size_for(target, knob.range[0], drawn, drawn / 2.0, vis);
        return (s, v, v_drawn);
    }
    if v_drawn >= target {
        return (drawn, v_drawn, v_drawn);
    }
    let (s, v) = size_for(target, drawn, knob.range[1], 2.0 * drawn, vis);
    (s, v, v_drawn)
}

/// A case planned: the world drawn, every effect sized and applied, the truth known; not
/// yet measured.
pub struct Plan {
    pub spec: Spec,
    pub design: Design,
    pub ctx: Context,
    /// The axis with everything added.
    pub plant: Plant,
    pub chain: Chain,
    pub viscous: f64,
    pub noise_factor: f64,
    pub sizes: Vec<Sizing>,
    /// The right answers (see [`Truth`]).
    pub effects: Vec<String>,
    pub band_hz: Option<[f64; 2]>,
    pub visibility: f64,
    pub visibility_true_chain: f64,
    /// Per sizing: `ln(H_with / H_refit)` at the applied size alone on the nominal axis
    /// (None where its response is not periodic).
    pub residuals: Vec<Option<Vec<Vec<flexid::Complex64>>>>,
    /// The noise model's line scatter per level and line.
    pub sigma: Vec<Vec<f64>>,
    /// The least visibility a diagnosis can be required to see.
    pub detectable: f64,
}

/// Draw the world of `spec` and size its effects (no recording yet).
/// The excitation kind [`plan`] draws for `spec` (the world drawn alone, no effect sized,
/// nothing simulated): to select cases by excitation before generating them.
pub fn drawn_kind(spec: &Spec) -> Kind {
    let mut rng = rand::rngs::StdRng::seed_from_u64(spec.seed ^ 0x3017_d1a6_0a1d);
    draw_world(spec, &mut rng, 1.0).design.kind
}

/// The plan of a case: drawn at the world's levels, and drawn again (the same draws) at
/// lower levels where they would swing an arm under gravity out of its linear range.
pub fn plan(spec: &Spec) -> Plan {
    let drawn = plan_at(spec, 1.0);
    match gravity_level_scale(&drawn) {
        Some(scale) => plan_at(spec, scale),
        None => drawn,
    }
}

/// The largest departure of the gravity stiffness's describing function from `m g l`
/// that a measurement of gravity as a linear effect may carry: 1 %.
const GRAVITY_LINEARITY: f64 = 0.01;

/// The factor that brings the high level's swing of an arm under gravity within
/// [`GRAVITY_LINEARITY`], None when it is within already (or there is no gravity).
///
/// A technician measuring an arm that hangs under gravity keeps its swing small, as the
/// linearised gravity stiffness `m g l` is only what the arm shows at small swings: for a
/// sine of amplitude `a` the describing function of `m g l sin q` is `m g l 2 J1(a)/a ~
/// m g l (1 - a^2/8)`; for a Gaussian swing of RMS `s` (a multisine) the mean slope is
/// `m g l exp(-s^2/2)`. Without the limit a swept or stepped sine near the swing's
/// resonance throws the arm over the top (seen: twelve half-turns).
fn gravity_level_scale(plan: &Plan) -> Option<f64> {
    let g = plan.plant.gravity.as_ref()?;
    let rms = plan.ctx.reference.levels_rms_nm[plan.ctx.high()];
    let lines = plan.design.grid_hz();
    let excess = match plan.design.kind {
        Kind::SweptSine | Kind::SteppedSine => {
            // a sine at each frequency in turn: amplitude sqrt(2) rms |H_body|
            let a_max = (8.0 * GRAVITY_LINEARITY).sqrt();
            let gain = lines
                .iter()
                .map(|&f| {
                    (analytic::drive(&plan.plant, f)
                        * analytic::body_positions(&plan.plant, f)[g.body])
                        .norm()
                })
                .fold(0.0, f64::max);
            std::f64::consts::SQRT_2 * rms * gain / a_max
        }
        _ => {
            let s_max = (-2.0 * (1.0 - GRAVITY_LINEARITY).ln()).sqrt();
            analytic::rms_motion(&plan.plant, plan.ctx.reference.motion_lines_hz(), rms)
                .position_rad[g.body]
                / s_max
        }
    };
    (excess > 1.0).then(|| 1.0 / excess)
}

fn plan_at(spec: &Spec, level_scale: f64) -> Plan {
    let mut rng = rand::rngs::StdRng::seed_from_u64(spec.seed ^ 0x3017_d1a6_0a1d);
    let world = draw_world(spec, &mut rng, level_scale);
    let ctx = &world.ctx;
    let judge = Judge::new(ctx);
    let names: Vec<&str> = match spec.group {
        Group::A if spec.class == "none" => vec![],
        Group::A | Group::B | Group::D => vec![spec.class],
        Group::C => spec.class.split('+').collect(),
        Group::E => vec![],
    };
    let knobs: Vec<Knob> = names
        .iter()
        .map(|c| {
            if spec.group == Group::D {
                cause(c, ctx, &mut rng)
            } else {
                effect(c, ctx, &mut rng)
            }
        })
        .collect();
    let mut plant = world.plant.clone();
    let mut sizes = Vec::new();
    let mut residuals = Vec::new();
    for k in &knobs {
        let target = log_uniform(&mut rng, 4.0, 10.0);
        let drawn = log_uniform(&mut rng, k.typical[0], k.typical[1]);
        let (full, v_full, v_drawn) = full_size(k, &judge, drawn, target);
        let size = if spec.group == Group::B {
            full / 3.0
        } else {
            full
        };
        let mut p = ctx.nominal.clone();
        k.apply(&mut p, size);
        let residual = judge.delta(&p, k.linear).map(|d| {
            let starts = absorbed(&ctx.nominal, &[(k, size)]);
            (judge.residual(&d, k.answer == "unexplained", &starts), d)
        });
        let (v, v_true) = residual.as_ref().map_or((f64::MAX, f64::MAX), |(r, d)| {
            (visibility(r, &judge.sigma), visibility(d, &judge.sigma))
        });
        residuals.push(residual.map(|r| r.0));
        k.apply(&mut plant, size);
        sizes.push(Sizing {
            class: k.class.into(),
            answer: k.answer.into(),
            size_name: k.size_name.into(),
            typical_size: drawn,
            typical_visibility: v_drawn,
            full_size: full,
            full_visibility: v_full,
            target_visibility: target,
            size,
            visibility: v,
            visibility_true_chain: v_true,
            visibility_measured: None,
            shape: k.shape.clone(),
        });
    }
    let linear = knobs.iter().all(|k| k.linear);
    let ((visibility_all, visibility_true), band_hz) = if knobs.is_empty() {
        ((0.0, 0.0), None)
    } else {
        match judge.delta(&plant, linear) {
            Some(delta) => {
                let band = (spec.group == Group::D)
                    .then(|| acting_band(&delta, &ctx.reference.lines_hz))
                    .flatten();
                let applied: Vec<(&Knob, f64)> =
                    knobs.iter().zip(&sizes).map(|(k, s)| (k, s.size)).collect();
                let starts = absorbed(&ctx.nominal, &applied);
                (
                    judge.visibility_of(&delta, spec.group == Group::D, &starts),
                    band,
                )
            }
            None => ((f64::MAX, f64::MAX), None),
        }
    };
    // an effect the data cannot show (a refit nominal chain absorbs it, or its range ends
    // below the detectable) is not required: the right answer is then `none`
    let detectable = judge.detectable();
    let effects = required(&sizes, detectable);
    Plan {
        spec: spec.clone(),
        design: world.design.clone(),
        ctx: world.ctx.clone(),
        plant,
        chain: world.chain.clone(),
        viscous: world.viscous,
        noise_factor: world.noise_factor,
        sizes,
        effects,
        band_hz,
        visibility: visibility_all,
        visibility_true_chain: visibility_true,
        residuals,
        sigma: judge.sigma.clone(),
        detectable,
    }
}

/// The effects a diagnosis is required to name: those of the library whose visibility
/// beyond the nominal model reaches `detectable`, by the noise model and, where the case's
/// recordings measured it, by their own scatter (an effect the data cannot show is not
/// required: the right answer is then `none`).
fn required(sizes: &[Sizing], detectable: f64) -> Vec<String> {
    sizes
        .iter()
        .filter(|s| s.answer != "unexplained" && shows(s, detectable))
        .map(|s| s.answer.clone())
        .collect()
}

/// Whether the data can show a sizing: its visibility beyond the nominal model (for a
/// cause outside the library, beyond a library delay too) reaches `detectable`, by the
/// noise model and, where the case's recordings measured it, by their own scatter.
fn shows(s: &Sizing, detectable: f64) -> bool {
    s.visibility >= detectable && s.visibility_measured.is_none_or(|v| v >= detectable)
}

/// Repeated recordings of a sweep that measure its scatter per line
/// ([`repeated_sigma_ln`]).
const REPEATS: u64 = 6;

/// The reading the estimate divides by the command: the velocity, or the position
/// differenced (its first sample repeated).
fn reading_of(out: &[super::simulator::Sample], velocity: bool) -> Vec<f64> {
    (0..out.len())
        .map(|i| {
            if velocity {
                out[i].velocity_rad_s
            } else {
                out[i].position_rad - out[i.saturating_sub(1)].position_rad
            }
        })
        .collect()
}

/// Generate `spec` into `dir` (created): two recordings `level0.csv`, `level1.csv` (low,
/// high) with their sidecars, and `truth.json`.
pub fn generate(spec: &Spec, dir: &Path) -> Case {
    measure(plan(spec), dir)
}

/// Measure a planned case at both levels (with noise drawn from its seed) into `dir`.
pub fn measure(plan: Plan, dir: &Path) -> Case {
    std::fs::create_dir_all(dir).unwrap();
    let (ctx, plant, spec) = (&plan.ctx, &plan.plant, &plan.spec);
    let steps = substeps(plant, ctx.fs_hz, &peaks_of(plant, ctx));
    let mut recordings = Vec::new();
    let mut samples = 0;
    let own_multisine = ctx.reference.own_periods.is_some();
    // a sweep's scatter from repeated recordings (its record is not periodic)
    let sweep = plan.design.kind == Kind::SweptSine;
    let mut measured_sigma = Vec::new();
    for (i, &rms) in ctx.reference.levels_rms_nm.iter().enumerate() {
        let (u, info) = plan.design.generate(rms);
        samples = u.len();
        let seed = spec.seed.wrapping_mul(10) + i as u64;
        let mut sim = Sim::new(plant, ctx.fs_hz, steps, seed, false);
        // centred on a period of a periodic excitation, else on the whole record
        let period = match info.period_samples {
            0 => u.len(),
            n => n.min(u.len()),
        };
        sim.start_centred(&u[..period]);
        let out = sim.run(&u);
        let fs = ctx.fs_hz;
        let velocity = plant.sensor.output == Output::Velocity;
        if own_multisine {
            let reading: Vec<f64> = if velocity {
                out.iter().map(|s| s.velocity_rad_s).collect()
            } else {
                out.iter().map(|s| s.position_rad).collect()
            };
            measured_sigma.push(measured_sigma_ln(
                &u,
                &reading,
                !velocity,
                &ctx.reference,
                plan.design.transient_periods,
                plan.design.periods,
                &plan.sigma[i],
            ));
        }
        if let Some(st) = &ctx.reference.stepped {
            let reading: Vec<f64> = if velocity {
                out.iter().map(|s| s.velocity_rad_s).collect()
            } else {
                out.iter().map(|s| s.position_rad).collect()
            };
            measured_sigma.push(measured_sigma_stepped(
                &st[i],
                &reading,
                !velocity,
                &plan.sigma[i],
            ));
        }
        if sweep {
            let runs: Vec<Vec<Complex64>> = (0..REPEATS)
                .map(|j| {
                    let mut sim = Sim::new(plant, fs, steps, seed.wrapping_mul(31) + 1 + j, false);
                    sim.start_centred(&u);
                    let y = reading_of(&sim.run(&u), velocity);
                    ln_h1_lines(
                        &u,
                        &y,
                        &ctx.reference.lines_hz,
                        fs,
                        plan.design.line_spacing_hz,
                    )
                })
                .collect();
            // the plant's own response, without noise or quantisation
            let mut exact = Sim::new(plant, fs, steps, 0, true);
            exact.start_centred(&u);
            let y = reading_of(&exact.run(&u), velocity);
            let lines = &ctx.reference.lines_hz;
            let exact = ln_h1_lines(&u, &y, lines, fs, plan.design.line_spacing_hz);
            measured_sigma.push(repeated_sigma_ln(&runs, &exact, &plan.sigma[i]));
        }
        let rec = Recording {
            time_s: (0..u.len()).map(|k| k as f64 / fs).collect(),
            position_rad: (!velocity).then(|| out.iter().map(|s| s.position_rad).collect()),
            velocity_rad_s: velocity.then(|| out.iter().map(|s| s.velocity_rad_s).collect()),
            acceleration_rad_s2: None,
            torque_actual_nm: Some(out.iter().map(|s| s.torque_actual_nm).collect()),
            torque_cmd_nm: u,
            sample_rate_hz: fs,
            sidecar: Sidecar {
                sample_rate_hz: Some(fs),
                excitation: Some(info),
                ..Sidecar::default()
            },
        };
        let p = dir.join(format!("level{i}.csv"));
        write_recording(&p, &rec).unwrap();
        recordings.push(p);
    }
    // each effect judged again against the scatter its recordings show
    let mut sizes = plan.sizes.clone();
    let mut effects = plan.effects.clone();
    if own_multisine || sweep || ctx.reference.stepped.is_some() {
        for (s, r) in sizes.iter_mut().zip(&plan.residuals) {
            s.visibility_measured = Some(
                r.as_ref()
                    .map_or(f64::MAX, |r| visibility(r, &measured_sigma)),
            );
        }
        effects = required(&sizes, plan.detectable);
    }
    let verdict = match spec.group {
        Group::A | Group::B => Some(effects.first().cloned().unwrap_or_else(|| "none".into())),
        Group::C => None,
        // a cause the data cannot show is not required either: the right answer is `none`
        Group::D => Some(
            if sizes.iter().any(|s| shows(s, plan.detectable)) {
                "unexplained"
            } else {
                "none"
            }
            .into(),
        ),
        Group::E => Some("none".into()),
    };
    let truth = Truth {
        group: spec.group,
        class: spec.class.into(),
        seed: spec.seed,
        masses: plan.chain.masses(),
        effects,
        verdict,
        no_steady_state: matches!(spec.group, Group::A | Group::B)
            && sizes.iter().any(|s| {
                s.answer != "unexplained" && s.visibility >= f64::MAX && shows(s, plan.detectable)
            }),
        band_hz: plan.band_hz,
        sizes,
        visibility: plan.visibility,
        visibility_true_chain: plan.visibility_true_chain,
        measurement: Measurement {
            fs_hz: ctx.fs_hz,
            excitation: plan.design.clone(),
            levels_rms_nm: ctx.reference.levels_rms_nm.clone(),
            encoder_bits: plant.sensor.encoder_bits,
            torque_noise_nm: plant.torque_noise_nm,
            noise_factor: plan.noise_factor,
            output: plant.sensor.output,
            substeps: steps,
            samples_per_level: samples,
        },
        nominal_chain: plan.chain.clone(),
        nominal_motor_viscous_nms_per_rad: plan.viscous,
        plant: plan.plant.clone(),
    };
    let truth_path = dir.join("truth.json");
    std::fs::write(&truth_path, serde_json::to_string_pretty(&truth).unwrap()).unwrap();
    Case {
        recordings,
        truth_path,
        truth,
    }
}
