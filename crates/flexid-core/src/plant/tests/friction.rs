//! Coulomb friction with stiction, and viscous friction, on the motor.

use super::*;

fn with_friction(chain: Chain, tc: f64, b: f64) -> PlantSpec {
    let mut spec = PlantSpec::linear(chain);
    spec.effects.friction = Some(Friction {
        coulomb_nm: tc,
        viscous_nms_per_rad: b,
    });
    spec
}

#[test]
fn torque_below_coulomb_leaves_the_motor_at_rest() {
    let spec = with_friction(chain3(), 0.2, 0.01);
    let mut sim = PlantSim::new(&spec, 2000.0, 10, 1).unwrap();
    // constant, then an oscillating torque, all below 0.2 N m
    let torque: Vec<f64> = (0..4000)
        .map(|k| {
            if k < 2000 {
                0.19
            } else {
                -0.19 * (k as f64 * 0.05).sin()
            }
        })
        .collect();
    for s in run(&mut sim, &torque) {
        assert_eq!(s.position_rad, 0.0, "{s:?}");
        assert_eq!(s.velocity_rad_s, 0.0);
        assert_eq!(s.load_position_rad, 0.0);
    }
    assert!(sim.is_stuck());
    // just above, it moves
    let mut sim = PlantSim::new(&spec, 2000.0, 10, 1).unwrap();
    for _ in 0..100 {
        sim.step(0.21);
    }
    assert!(sim.sample().position_rad > 0.0);
}

#[test]
fn torque_above_coulomb_accelerates_the_chain_at_the_excess_over_total_inertia() {
    let chain = chain2(); // stiff and damped: a rigid chain after the transient
    let jt = chain.total_inertia();
    for (t, tc) in [(0.5, 0.2), (-0.5, 0.2), (0.3, 0.0)] {
        let spec = with_friction(chain.clone(), tc, 0.0);
        let fs = 2000.0;
        let mut sim = PlantSim::new(&spec, fs, 10, 1).unwrap();
        let s: Vec<AxisSample> = run(&mut sim, &vec![t; 1000]).collect();
        let (a, b) = (&s[400], &s[999]);
        let acc = (b.velocity_rad_s - a.velocity_rad_s) / (b.time_s - a.time_s);
        let want = (t - tc * f64::signum(t)) / jt;
        assert!(
            (acc - want).abs() < 1e-6 * want.abs(),
            "T {t}: {acc} vs {want}"
        );
    }
}

/// A lone motor from rest under `T > Tc`: `w(t) = (T - Tc)/b (1 - e^{-b t / J})`.
#[test]
fn viscous_friction_gives_the_first_order_velocity() {
    let (j, tc, b, t) = (1e-3, 0.1, 0.01, 0.3);
    let spec = with_friction(Chain::new(vec![j], vec![], vec![]).unwrap(), tc, b);
    let mut sim = PlantSim::new(&spec, 1000.0, 10, 1).unwrap();
    for s in run(&mut sim, &vec![t; 2000]) {
        let want = (t - tc) / b * (1.0 - (-b * s.time_s / j).exp());
        assert!(
            (s.velocity_rad_s - want).abs() < 1e-9 * (t - tc) / b,
            "{s:?} vs {want}"
        );
    }
}

/// After the torque is removed the motor decelerates at `Tc / J`, stops at `w0 J / Tc`,
/// and then stays exactly still.
#[test]
fn coulomb_friction_stops_the_motor_and_holds_it() {
    let (j, tc) = (1e-3, 0.1);
    let spec = with_friction(Chain::new(vec![j], vec![], vec![]).unwrap(), tc, 0.0);
    let fs = 1000.0;
    let mut sim = PlantSim::new(&spec, fs, 10, 1).unwrap();
    let mut torque = vec![0.0; 1000];
    torque[..100].fill(0.3); // w0 = 0.2 * 0.1 / 1e-3 = 20 rad/s at 0.1 s
    let s: Vec<AxisSample> = run(&mut sim, &torque).collect();
    let w0 = (0.3 - tc) * 0.1 / j;
    let t_stop = 0.1 + w0 * j / tc; // 0.3 s
    for x in &s[101..] {
        let want = (w0 - tc / j * (x.time_s - 0.1)).max(0.0);
        assert!((x.velocity_rad_s - want).abs() < 1e-9, "{x:?} vs {want}");
    }
    let rest = s[(t_stop * fs) as usize + 1].position_rad;
    let p_stop = 0.5 * (0.3 - tc) / j * 0.01 + w0 * w0 * j / (2.0 * tc);
    assert!((rest - p_stop).abs() < 1e-9 * p_stop, "{rest} vs {p_stop}");
    assert!(s[(t_stop * fs) as usize + 1..]
        .iter()
        .all(|x| x.position_rad == rest && x.velocity_rad_s == 0.0));
    assert!(sim.is_stuck());
}

/// A drift through Coulomb friction: with an initial velocity the motor keeps slipping one
/// way and the friction is a constant torque.
#[test]
fn initial_velocity_keeps_the_motor_slipping() {
    let chain = chain2();
    let spec = with_friction(chain.clone(), 0.05, 0.0);
    let mut sim = PlantSim::new(&spec, 2000.0, 10, 1).unwrap();
    sim.set_initial_velocity(10.0);
    let s: Vec<AxisSample> = run(&mut sim, &vec![0.0; 200]).collect();
    let want = 10.0 - 0.05 / chain.total_inertia() * s[199].time_s;
    assert!(
        (s[199].velocity_rad_s - want).abs() < 1e-3,
        "{} vs {want}",
        s[199].velocity_rad_s
    );
    assert!(!sim.is_stuck());
}

/// Stick-slip under a sine 1.2 times the Coulomb torque (lone motor: it comes to rest
/// before the command falls below -Tc): at every cycle end the motor is held
/// exactly when the held command is within the Coulomb torque and it has come to rest;
/// never held while the command exceeds it, and it dwells at rest between the slips.
#[test]
fn sine_above_coulomb_sticks_only_below_coulomb() {
    let (j, tc) = (1e-3, 0.1);
    let spec = with_friction(Chain::new(vec![j], vec![], vec![]).unwrap(), tc, 1e-4);
    let mut sim = PlantSim::new(&spec, 1000.0, 10, 1).unwrap();
    let (mut stuck_cycles, mut slip_cycles) = (0, 0);
    for k in 0..4000 {
        let u = 1.2 * tc * (2.0 * PI * k as f64 / 200.0).sin();
        let before = sim.sample();
        sim.step(u);
        if sim.is_stuck() {
            stuck_cycles += 1;
            assert!(u.abs() <= tc, "held at cycle {k} with command {u}");
            assert_eq!(sim.sample().velocity_rad_s, 0.0);
        } else {
            slip_cycles += 1;
        }
        if u.abs() > tc && before.velocity_rad_s == 0.0 {
            assert!(!sim.is_stuck(), "breakaway at cycle {k}");
        }
    }
    assert!(
        stuck_cycles > 400 && slip_cycles > 400,
        "{stuck_cycles} stuck, {slip_cycles} slipping"
    );
}
