//! The right-hand side of the plant's equations of motion (all effects), allocation-free.

use super::PlantSpec;
use crate::model::Chain;

/// Immutable parameters of the equations of motion, derived from a [`PlantSpec`].
///
/// State layout `y = [theta_1..theta_n, omega_1..omega_n, tau, tau']` [rad, rad/s, N m,
/// N m/s], with `tau` (and `tau'`) present only for a current loop of order 1 (2).
#[derive(Debug, Clone)]
pub(crate) struct Dynamics {
    /// Bodies of the simulated (extended) chain.
    pub n: usize,
    pub inv_j: Vec<f64>,
    pub stiffness: Vec<f64>,
    pub damping: Vec<f64>,
    /// Backlash: (coupling, half gap [rad]).
    pub backlash: Option<(usize, f64)>,
    /// Hardening: (coupling, 1/x_ref^2 [1/rad^2]).
    pub hardening: Option<(usize, f64)>,
    /// Coulomb friction [N m] (0 = none).
    pub coulomb: f64,
    /// Viscous friction [N m s/rad].
    pub viscous: f64,
    /// Gravity `m g l` [N m] and offset [rad] (mgl 0 = none).
    pub mgl: f64,
    pub offset: f64,
    /// Current-loop order (0 = ideal), `wc` [rad/s], damping ratio.
    pub loop_order: usize,
    pub wc: f64,
    pub zeta: f64,
}

/// Discrete mode of the friction model, fixed over one sub-step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct FrictionMode {
    /// The motor is stuck (held at rest by static friction).
    pub stuck: bool,
    /// Direction of slip (+1 or -1) while not stuck: the Coulomb torque is `-Tc dir`.
    pub dir: f64,
}

impl Dynamics {
    pub fn new(spec: &PlantSpec) -> Self {
        let chain: Chain = spec.extended_chain();
        let e = &spec.effects;
        let (loop_order, wc, zeta) = match &e.current_loop {
            None => (0, 0.0, 0.0),
            Some(c) => (
                usize::from(c.order),
                2.0 * std::f64::consts::PI * c.bandwidth_hz,
                c.damping_ratio,
            ),
        };
        Dynamics {
            n: chain.masses(),
            inv_j: chain.inertia_kgm2.iter().map(|j| 1.0 / j).collect(),
            stiffness: chain.stiffness_nm_per_rad.clone(),
            damping: chain.damping_nms_per_rad.clone(),
            backlash: e.backlash.as_ref().map(|b| (b.coupling, b.half_gap_rad)),
            hardening: e
                .hardening_stiffness
                .as_ref()
                .map(|h| (h.coupling, 1.0 / (h.x_ref_rad * h.x_ref_rad))),
            coulomb: e.friction.as_ref().map_or(0.0, |f| f.coulomb_nm),
            viscous: e.friction.as_ref().map_or(0.0, |f| f.viscous_nms_per_rad),
            mgl: e.gravity.as_ref().map_or(0.0, |g| g.m_g_l_nm),
            offset: e.gravity.as_ref().map_or(0.0, |g| g.offset_rad),
            loop_order,
            wc,
            zeta,
        }
    }

    /// Length of the state vector.
    pub fn dim(&self) -> usize {
        2 * self.n + self.loop_order
    }

    /// Motor torque [N m] in state `y` with delayed command `u` (the current loop's output).
    #[inline]
    pub fn motor_torque(&self, y: &[f64], u: f64) -> f64 {
        if self.loop_order == 0 {
            u
        } else {
            y[2 * self.n]
        }
    }

    /// Torque [N m] of coupling `i` on body `i` (the negative acts on body `i+1`), for
    /// deflection `x = theta_(i+1) - theta_i` and its rate `v`.
    #[inline]
    pub fn coupling_torque(&self, i: usize, x: f64, v: f64) -> f64 {
        let mut xe = x;
        let mut contact = true;
        if let Some((k, g)) = self.backlash {
            if k == i {
                if x > g {
                    xe = x - g;
                } else if x < -g {
                    xe = x + g;
                } else {
                    xe = 0.0;
                    contact = false;
                }
            }
        }
        let mut spring = self.stiffness[i] * xe;
        if let Some((k, inv_xref2)) = self.hardening {
            if k == i {
                spring *= 1.0 + xe * xe * inv_xref2;
            }
        }
        if contact {
            spring + self.damping[i] * v
        } else {
            0.0
        }
    }

    /// All torques [N m] on the bodies except friction, into `tq` (length `n`).
    #[inline]
    pub fn torques(&self, y: &[f64], u: f64, disturbance: f64, tq: &mut [f64]) {
        let n = self.n;
        tq.fill(0.0);
        tq[0] = self.motor_torque(y, u) + disturbance;
        for i in 0..n - 1 {
            let f = self.coupling_torque(i, y[i + 1] - y[i], y[n + i + 1] - y[n + i]);
            tq[i] += f;
            tq[i + 1] -= f;
        }
        if self.mgl != 0.0 {
            tq[n - 1] -= self.mgl * (y[n - 1] + self.offset).sin();
        }
    }

    /// `dy = f(y)` for delayed command `u` [N m], disturbance torque [N m] and friction mode.
    #[inline]
    pub fn deriv(&self, y: &[f64], u: f64, disturbance: f64, mode: FrictionMode, dy: &mut [f64]) {
        let n = self.n;
        let (pos, rest) = dy.split_at_mut(n);
        let (acc, lp) = rest.split_at_mut(n);
        pos.copy_from_slice(&y[n..2 * n]);
        self.torques(y, u, disturbance, acc);
        if self.coulomb > 0.0 && mode.stuck {
            acc[0] = 0.0;
            pos[0] = 0.0;
        } else {
            let mut fr = self.viscous * y[n];
            if self.coulomb > 0.0 {
                fr += self.coulomb * mode.dir;
            }
            acc[0] -= fr;
        }
        for (a, ij) in acc.iter_mut().zip(&self.inv_j) {
            *a *= ij;
        }
        match self.loop_order {
            1 => lp[0] = self.wc * (u - y[2 * n]),
            2 => {
                lp[0] = y[2 * n + 1];
                lp[1] =
                    self.wc * self.wc * (u - y[2 * n]) - 2.0 * self.zeta * self.wc * y[2 * n + 1];
            }
            _ => {}
        }
    }

    /// Largest eigenvalue magnitude [1/s] of the plant linearised about rest (springs in
    /// contact, hardening at zero deflection, gravity as a spring), for the step-size check.
    pub fn lambda_max(&self) -> f64 {
        let n = self.n;
        let m = 2 * n;
        let mut a = nalgebra::DMatrix::<f64>::zeros(m, m);
        for i in 0..n {
            a[(i, n + i)] = 1.0;
        }
        for i in 0..n - 1 {
            let (c, d) = (self.stiffness[i], self.damping[i]);
            for (row, sign) in [(i, 1.0), (i + 1, -1.0)] {
                let ij = self.inv_j[row];
                a[(n + row, i)] -= sign * c * ij;
                a[(n + row, i + 1)] += sign * c * ij;
                a[(n + row, n + i)] -= sign * d * ij;
                a[(n + row, n + i + 1)] += sign * d * ij;
            }
        }
        a[(n, n)] -= self.viscous * self.inv_j[0];
        a[(2 * n - 1, n - 1)] -= self.mgl * self.offset.cos().abs() * self.inv_j[n - 1];
        // the Gershgorin bound where the eigenvalues do not converge: larger, so safe for
        // the step-size check
        let chain_max = crate::model::eigen::eigenvalues(&a)
            .map(|ev| ev.iter().map(|l| l.norm()).fold(0.0, f64::max))
            .unwrap_or_else(|| crate::model::eigen::spectral_radius_bound(&a));
        let loop_max = match self.loop_order {
            0 => 0.0,
            1 => self.wc,
            // roots of s^2 + 2 zeta wc s + wc^2: |s| = wc for zeta <= 1, larger root otherwise
            _ => self.wc * (self.zeta + (self.zeta * self.zeta - 1.0).max(0.0).sqrt()),
        };
        chain_max.max(loop_max)
    }
}
