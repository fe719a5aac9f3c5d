//! Guards of a mechanism run: the divergence guard and the step-size guard.
//!
//! # Divergence guard
//! After every accepted step ([`crate::ode::OdeSystem::check_step`]) the run stops with
//! [`crate::Error::Diverged`] at the first of:
//! * a contact whose penetration is not finite or exceeds the limit (the scene's
//!   `solver.max_penetration`, else one tenth of the joint's journal radius,
//!   [`crate::clearance::Geometry::runaway_penetration`]); the message names the clearance joint,
//!   the contact and the penetration;
//! * a constraint residual |Phi_i| beyond `solver.max_constraint_drift` (default 0.1 m or rad; a runaway grows exponentially and crosses any such level within a few steps, while a stable run without stabilisation may drift by centimetres over hundreds of periods),
//!   naming the joint or drive that owns the row.
//!
//! A state that becomes non-finite is explained by [`Model::explain_non_finite`]: the body and
//! coordinate, and the deepest contact at the last finite state.
//!
//! # Step-size guard
//! An explicit method with a fixed step h is stable for a linear mode `exp(lambda t)` only while
//! |R(h lambda)| <= 1, R its stability function ([`crate::ode::Method::amplification`]). Each
//! active contact is linearised about its current state as one degree of freedom along its
//! normal,
//!
//! ```text
//!   m x'' + c x' + k x = 0,   k = dF/d(delta),  c = dF/d(delta_dot),
//!   lambda = (-c -+ sqrt(c^2 - 4 m k)) / (2 m),
//! ```
//!
//! with m the effective mass of the mechanism along the contact normal: with the generalised
//! direction w of the normal (the contact point's normal velocity is w v),
//! `1/m = w M^-1 w^T - u^T S^+ u`, `u = G M^-1 w^T`, S = G M^-1 G^T the reduced matrix of the
//! constraints (its factorisation from the last evaluation is reused). The friction law adds a
//! damper `c_t = F_N dc/dv` (or `F_N c(v)/v` across the sliding direction, whichever is larger)
//! along the sliding direction, with its own effective mass. A mode outside the region triggers
//! one warning per joint, with the time, the mode and a step: half the largest stable step,
//! rounded down to 1, 2 or 5 times a power of ten. The guard runs on the assembled initial state
//! ([`crate::dynamics::Mechanism::check_initial`]) and after every accepted step, on the deepest
//! state each contact reached over the step's stages: a step that overshoots into a contact can
//! leave it again before the step ends.
//!
//! A lubricated joint's oil film is linearised the same way along its eccentricity, at every
//! state (`crate::film::Film::linearised`: the film's stiffness and damping there), with the
//! effective mass at the journal centre.
//!
//! Ignoring the constraints can only lower the effective mass (the subtracted term is a
//! quadratic form of a positive semi-definite matrix), which raises the mode's frequency and
//! damping rate; the guard first tests that cheap bound and solves with the constraints only
//! when the bound is unstable.

use nalgebra::Vector3;

use crate::clearance::{Clearance, ContactEval, sliding_velocity};
use crate::contact::FrictionLaw;
use crate::kin::{GROUND, Kin, any_normal};
use crate::model::Model;
use crate::ode::Method;
use crate::workspace::{Workspace, minv_block};

/// A warning raised while the run goes on.
#[derive(Debug, Clone, PartialEq)]
pub struct Warning {
    /// Simulated time (s).
    pub time: f64,
    pub message: String,
}

/// A clearance contact that penetrates at a run's start: its journal starts inside its
/// housing's wall, and the contact law pushes it out with the force of that depth at once.
#[derive(Debug, Clone, PartialEq)]
pub struct StartPenetration {
    pub joint: String,
    pub contact: String,
    /// Penetration (m).
    pub depth: f64,
    /// The law's elastic normal force at that depth (N; at zero penetration rate).
    pub force: f64,
}

impl std::fmt::Display for StartPenetration {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "clearance joint '{}', contact '{}': the journal starts {:.4e} m inside the housing's \
             wall, where the contact law pushes with {:.4e} N; the joint starts free (start = \
             \"free\"), so the declared poses place the journal: put it inside its clearance, \
             or let the start close the joint (start = \"closed\")",
            self.joint, self.contact, self.depth, self.force
        )
    }
}

/// Per-run state of the step-size guard: which joints have been warned about.
#[derive(Debug, Clone, Default)]
pub struct StepGuard {
    warned: Vec<bool>,
    /// Scratch of the constrained effective mass (one entry per constraint row).
    u: Vec<f64>,
    x: Vec<f64>,
}

impl StepGuard {
    /// Whether each clearance joint has been warned about (part of the run's hybrid state).
    pub fn warned(&self, n_clearances: usize) -> Vec<bool> {
        let mut w = self.warned.clone();
        w.resize(n_clearances, false);
        w
    }

    pub fn set_warned(&mut self, warned: &[bool]) {
        self.warned.clear();
        self.warned.extend_from_slice(warned);
    }
}

/// `M^-1 w^T` of the journal and housing bodies (ground: [`GROUND`]).
type Blocks = [(usize, [f64; 6]); 2];

/// A largest stable step `h`, halved and rounded down to 1, 2 or 5 times a power of ten.
fn suggested_step(h: f64) -> f64 {
    let x = 0.5 * h;
    let p = 10f64.powf(x.log10().floor());
    let m = x / p;
    let d = if m >= 5.0 {
        5.0
    } else if m >= 2.0 {
        2.0
    } else {
        1.0
    };
    d * p
}

/// The faster mode of a damper-spring (`k` N/m, `c` N s/m) on the mass `1/inv_m` (kg): its
/// eigenvalue `(re, im)` (1/s; the upper one of a complex pair) and the mass; None when the
/// inverse mass is not positive.
fn fastest_mode((k, c): (f64, f64), inv_m: f64) -> Option<((f64, f64), f64)> {
    if inv_m.is_nan() || inv_m <= 0.0 {
        return None;
    }
    let m = 1.0 / inv_m;
    let disc = c * c - 4.0 * m * k;
    let lambda = if disc < 0.0 {
        (-c / (2.0 * m), (-disc).sqrt() / (2.0 * m))
    } else {
        ((-c - disc.sqrt()) / (2.0 * m), 0.0)
    };
    Some((lambda, m))
}

impl Model {
    /// The clearance contacts that penetrate at the state `y` by more than a nanometre, deepest
    /// first: a start state whose journal lies inside its housing's wall.
    pub fn penetrations(&self, y: &[f64], ws: &mut Workspace) -> Vec<StartPenetration> {
        let mut out = Vec::new();
        if !self.effects.clearance {
            return out;
        }
        self.each_penetration(y, ws, |c, name, d| {
            if d > 1e-9 {
                out.push(StartPenetration {
                    joint: c.name.clone(),
                    contact: name.to_string(),
                    depth: d,
                    // At zero rate the damping of every law vanishes (its onset velocity then
                    // does not matter).
                    force: c.law.force(d, 0.0, 1.0),
                });
            }
        });
        out.sort_by(|a, b| b.depth.total_cmp(&a.depth));
        out
    }

    /// Calls `f(clearance, contact name, penetration in m)` for every contact of every clearance
    /// joint at the state `y` (its geometry evaluated into `ws`).
    fn each_penetration(
        &self,
        y: &[f64],
        ws: &mut Workspace,
        mut f: impl FnMut(&Clearance, &str, f64),
    ) {
        self.kinematics(y, ws);
        for c in &self.clearances {
            let slots = c.first..c.first + c.geometry.n_contacts();
            let (kh, kj) = (*self.kin_of(c.housing, ws), *self.kin_of(c.journal, ws));
            c.geometry(&kh, &kj, &mut ws.contacts[slots]);
            for (k, name) in c.geometry.contact_names().iter().enumerate() {
                f(c, name, ws.contacts[c.first + k].delta);
            }
        }
    }

    /// The linearised normal mode of every penetrating contact (the step-size guard's, above) at
    /// the state of the last evaluation in `ws`: its kinematics, contact states, onset history
    /// and constraint factorisation. `out[s]` is the eigenvalue `(re, im)` (1/s) of contact slot
    /// `s`'s faster mode with the constrained effective mass, None for a contact that does not
    /// penetrate or whose law gives no stiffness and no damping there. A contact without an
    /// onset velocity yet uses its penetration rate in its place, as its force does. With an
    /// integrator's stability function it tells whether a step was bounded by a contact's
    /// stability or by accuracy (`crates/solver/examples/step_census.rs`).
    pub fn contact_modes(&self, ws: &mut Workspace, out: &mut Vec<Option<(f64, f64)>>) {
        out.clear();
        out.resize(self.n_contacts, None);
        if !self.effects.clearance {
            return;
        }
        let (mut u, mut x) = (Vec::new(), Vec::new());
        for cl in &self.clearances {
            for s in cl.first..cl.first + cl.geometry.n_contacts() {
                let ce = ws.contacts[s];
                if ce.delta.is_nan() || ce.delta <= 0.0 || ce.n.norm() == 0.0 {
                    continue;
                }
                let onset = if ws.onset[s].is_nan() {
                    ce.delta_dot
                } else {
                    ws.onset[s]
                };
                let kc = cl.law.linearised(ce.delta, ce.delta_dot, onset);
                if kc == (0.0, 0.0) {
                    // No force depends on the penetration here: no mode.
                    continue;
                }
                let free = self.free_inverse_mass(cl, &ce.n, (&ce.pj, &ce.ph), ws);
                let inv_m = self.constrained((free.0, &free.1), ws, (&mut u, &mut x));
                out[s] = fastest_mode(kc, inv_m).map(|(lambda, _)| lambda);
            }
        }
    }

    fn kin_of<'w>(&self, b: usize, ws: &'w Workspace) -> &'w Kin {
        &ws.kin[if b == GROUND { self.nb() } else { b }]
    }

    /// The first runaway quantity at the state of the last evaluation, or None.
    pub fn runaway(&self, ws: &Workspace) -> Option<String> {
        if self.effects.clearance {
            for c in &self.clearances {
                let limit = self
                    .settings
                    .max_penetration
                    .unwrap_or_else(|| c.geometry.runaway_penetration());
                for (k, name) in c.geometry.contact_names().iter().enumerate() {
                    let d = ws.contacts[c.first + k].delta;
                    if !d.is_finite() || d > limit {
                        let source = if self.settings.max_penetration.is_some() {
                            "solver.max_penetration"
                        } else {
                            "one tenth of the journal radius, or of a slider's half-height; set solver.max_penetration to change it"
                        };
                        return Some(format!(
                            "clearance joint '{}', contact '{name}': penetration {d:.4e} m exceeds \
                             the runaway limit {limit:.4e} m ({source}): the integration is \
                             unstable; use a smaller step or an adaptive integrator",
                            c.name
                        ));
                    }
                }
            }
        }
        if self.effects.constraints {
            let max = self.settings.max_drift;
            if let Some(i) = (0..self.n_rows).find(|&i| ws.phi[i].is_nan() || ws.phi[i].abs() > max)
            {
                return Some(format!(
                    "constraint residual of {} reached {:.4e} (m or rad), beyond \
                     solver.max_constraint_drift = {max:e}",
                    self.row_owner(i),
                    ws.phi[i]
                ));
            }
        }
        None
    }

    /// Explains why component `i` of the state became non-finite in the step after `(t, y)`.
    pub fn explain_non_finite(&self, t: f64, y: &[f64], i: usize, ws: &mut Workspace) -> String {
        let np = self.n_pos();
        let what = if i < np {
            let names = [
                "x position",
                "y position",
                "z position",
                "Euler parameter w",
                "Euler parameter x",
                "Euler parameter y",
                "Euler parameter z",
            ];
            format!("{} of body '{}'", names[i % 7], self.bodies[i / 7].name)
        } else if i >= self.bristle_offset() {
            let names = self.bristle_names();
            let name = names
                .get(i - self.bristle_offset())
                .map_or("?", |n| n.as_str());
            format!("LuGre bristle deflection '{name}'")
        } else {
            let j = i - np;
            let names = [
                "x velocity",
                "y velocity",
                "z velocity",
                "x angular velocity",
                "y angular velocity",
                "z angular velocity",
            ];
            format!("{} of body '{}'", names[j % 6], self.bodies[j / 6].name)
        };
        let mut msg = format!("the {what} became non-finite in the step after t = {t} s");
        if self.effects.clearance && y.iter().all(|v| v.is_finite()) {
            let mut deepest: Option<(f64, String)> = None;
            self.each_penetration(y, ws, |c, name, d| {
                if deepest.as_ref().is_none_or(|(e, _)| d > *e) {
                    deepest = Some((d, format!("clearance joint '{}', contact '{name}'", c.name)));
                }
            });
            if let Some((d, which)) = deepest {
                msg += &format!(
                    "; at that last finite state the deepest contact was {which}, penetration \
                     {d:.4e} m"
                );
            }
        }
        msg
    }

    /// The two bodies' share of the inverse effective mass (1/kg) for a unit force pair along
    /// `dir` at the journal point `pj` and the housing point `ph` of clearance joint `c`:
    /// `w M^-1 w^T`, with the blocks `M^-1 w^T` of journal and housing for [`Model::constrained`].
    fn free_inverse_mass(
        &self,
        c: &Clearance,
        dir: &Vector3<f64>,
        (pj, ph): (&Vector3<f64>, &Vector3<f64>),
        ws: &Workspace,
    ) -> (f64, Blocks) {
        let mut blocks = [(GROUND, [0.0; 6]); 2];
        let mut inv = 0.0;
        for (slot, (b, p, sign)) in [(c.journal, pj, 1.0), (c.housing, ph, -1.0)]
            .into_iter()
            .enumerate()
        {
            if b == GROUND {
                continue;
            }
            let r = p - ws.kin[b].r;
            let m = r.cross(dir);
            let w = [
                sign * dir.x,
                sign * dir.y,
                sign * dir.z,
                sign * m.x,
                sign * m.y,
                sign * m.z,
            ];
            let mw = minv_block(self, ws, b, &w);
            inv += (0..6).map(|k| w[k] * mw[k]).sum::<f64>();
            blocks[slot] = (b, mw);
        }
        (inv, blocks)
    }

    /// The inverse effective mass with the constraints: `inv0 - u^T S^+ u`, `u = G M^-1 w^T`
    /// from the blocks of [`Model::free_inverse_mass`], in the guard's scratch vectors.
    fn constrained(
        &self,
        (inv0, blocks): (f64, &Blocks),
        ws: &mut Workspace,
        (u, x): (&mut Vec<f64>, &mut Vec<f64>),
    ) -> f64 {
        if self.n_rows == 0 || !self.effects.constraints {
            return inv0;
        }
        u.clear();
        u.resize(self.n_rows, 0.0);
        for (i, row) in ws.rows.iter().enumerate() {
            for (b, mw) in blocks {
                if *b == GROUND {
                    continue;
                }
                for (rb, j) in [(row.a, &row.ja), (row.b, &row.jb)] {
                    if rb == *b {
                        u[i] += (0..6).map(|k| j[k] * mw[k]).sum::<f64>();
                    }
                }
            }
        }
        x.clone_from(u);
        ws.solve_reduced(x);
        inv0 - u.iter().zip(x.iter()).map(|(a, b)| a * b).sum::<f64>()
    }

    /// The fastest mode of a damper-spring (`k` N/m, `c` N s/m) on the effective mass, when
    /// unstable at step `h`: tested first on the two bodies' mass `free` (from
    /// [`Model::free_inverse_mass`]), then with the constraints. Returns its eigenvalue and mass,
    /// and the largest stable step.
    fn unstable_mode(
        &self,
        (method, h): (&Method, f64),
        (k, c): (f64, f64),
        free: (f64, &Blocks),
        ws: &mut Workspace,
        scratch: (&mut Vec<f64>, &mut Vec<f64>),
    ) -> Option<((f64, f64), f64, f64)> {
        let mode = |inv_m: f64| -> Option<((f64, f64), f64)> {
            let (lambda, m) = fastest_mode((k, c), inv_m)?;
            let a = method.amplification(h * lambda.0, h * lambda.1)?;
            (a > 1.0 + 1e-12).then_some((lambda, m))
        };
        mode(free.0)?;
        let (lambda, m) = mode(self.constrained(free, ws, scratch))?;
        let stable = method.stable_step(lambda.0, lambda.1, h)?;
        Some((lambda, m, stable))
    }

    /// The step-size guard at time `t` for the contact states `(starts, contacts)`: at the start
    /// of the step and the deepest of its stages, with the masses of the last evaluation. Gives
    /// a warning for each clearance joint not yet warned about whose contact has a mode the
    /// fixed step cannot follow stably.
    ///
    /// A contact that begins inside a step too long for it is overshot: its stages penetrate far
    /// deeper than the impact would. The contact is then linearised at the penetration where the
    /// approach at the step's start (speed v0, effective mass m) would stop, elastic energy =
    /// m v0^2 / 2, with v0 as the onset velocity.
    pub fn step_guard(
        &self,
        t: f64,
        (starts, contacts): (&[ContactEval], &[ContactEval]),
        ws: &mut Workspace,
        guard: &mut StepGuard,
        out: &mut Vec<Warning>,
    ) {
        let method = self.settings.method;
        let Some(h) = method.fixed_step() else {
            return;
        };
        if !self.effects.clearance {
            return;
        }
        guard.warned.resize(self.clearances.len(), false);
        for (ci, cl) in self.clearances.iter().enumerate() {
            if guard.warned[ci] {
                continue;
            }
            for (slot, name) in cl.geometry.contact_names().iter().enumerate() {
                let s = cl.first + slot;
                let ce = contacts[s];
                if ce.delta.is_nan() || ce.delta <= 0.0 || ce.n.norm() == 0.0 {
                    continue;
                }
                let points = (&ce.pj, &ce.ph);
                let (inv0, blocks) = self.free_inverse_mass(cl, &ce.n, points, ws);
                let v0 = starts[s].delta_dot;
                let (k, c) = if starts[s].delta <= 0.0 && v0 > 0.0 {
                    let m = 1.0 / inv0;
                    let target = 0.5 * m * v0 * v0;
                    let (mut lo, mut hi) = (0.0, ce.delta);
                    if cl.law.elastic_energy(hi) > target {
                        for _ in 0..100 {
                            let mid = 0.5 * (lo + hi);
                            if cl.law.elastic_energy(mid) > target {
                                hi = mid
                            } else {
                                lo = mid
                            }
                        }
                    }
                    let onset = if ws.onset[s].is_nan() {
                        v0
                    } else {
                        ws.onset[s]
                    };
                    cl.law.linearised(hi, 0.0, onset)
                } else {
                    cl.law.linearised(ce.delta, ce.delta_dot, ws.onset[s])
                };
                let mut found = self
                    .unstable_mode(
                        (&method, h),
                        (k, c),
                        (inv0, &blocks),
                        ws,
                        (&mut guard.u, &mut guard.x),
                    )
                    .map(|m| {
                        (
                            m,
                            format!("normal stiffness {k:.3e} N/m, damping {c:.3e} N s/m"),
                        )
                    });
                if found.is_none() && !cl.friction.is_none() && ce.fn_ > 0.0 {
                    let (kh, kj) = (self.kin_of(cl.housing, ws), self.kin_of(cl.journal, ws));
                    let vt = sliding_velocity(kh, kj, &ce);
                    let speed = vt.norm();
                    let dir = if speed > 0.0 {
                        vt / speed
                    } else {
                        any_normal(&ce.n)
                    };
                    // A memoryless law acts as a damper of F_N c(v) / v (its secant) or of its
                    // slope; LuGre's bristles as a spring of sigma0 F_N with the damper
                    // (sigma1 + sigma2) F_N (its secant c(v) / v is no damping: it grows
                    // without bound in stick, where the force is the bristles' spring).
                    let (kt, ct) = match cl.friction {
                        FrictionLaw::LuGre { sigma0, .. } => {
                            (ce.fn_ * sigma0, ce.fn_ * cl.friction.slope(speed))
                        }
                        FrictionLaw::None
                        | FrictionLaw::Coulomb { .. }
                        | FrictionLaw::Ambrosio { .. }
                        | FrictionLaw::Threlfall { .. } => {
                            let mut slope = cl.friction.slope(speed);
                            if speed > 0.0 {
                                slope = slope.max(cl.friction.coefficient(speed) / speed);
                            }
                            (0.0, ce.fn_ * slope)
                        }
                    };
                    let (inv_t, blocks_t) = self.free_inverse_mass(cl, &dir, points, ws);
                    found = self
                        .unstable_mode(
                            (&method, h),
                            (kt, ct),
                            (inv_t, &blocks_t),
                            ws,
                            (&mut guard.u, &mut guard.x),
                        )
                        .map(|m| {
                            let what = if kt > 0.0 {
                                format!("bristle stiffness {kt:.3e} N/m, friction damping {ct:.3e} N s/m (sliding speed {speed:.3e} m/s)")
                            } else {
                                format!("friction damping {ct:.3e} N s/m (sliding speed {speed:.3e} m/s)")
                            };
                            (m, what)
                        });
                }
                if let Some((found, what)) = found {
                    guard.warned[ci] = true;
                    out.push(unstable_warning(
                        t,
                        &format!("clearance joint '{}', contact '{name}'", cl.name),
                        found,
                        &what,
                        &method,
                    ));
                    break;
                }
            }
            // LuGre's bristles relax at lambda = sigma0 |v_t| / g(|v_t|), in and out of
            // contact. A fixed step that cannot follow them goes wrong before it goes unstable
            // (RK4's bound is h lambda = 2.78), and it goes wrong quietly: its run settles where
            // lambda is smaller. Measured on the stick-slip block with RK4: at h = 5e-5 s
            // (h lambda up to 1.85) the slips match the adaptive run's to 1e-5 m/s; at
            // h = 1.2e-4 s the run slips at half the speed, where h lambda peaks at 2.2. So
            // h lambda > 2 is warned about.
            if let (false, FrictionLaw::LuGre { sigma0, .. }) = (guard.warned[ci], cl.friction) {
                let (kh, kj) = (self.kin_of(cl.housing, ws), self.kin_of(cl.journal, ws));
                let slots = cl.first..cl.first + cl.geometry.n_contacts();
                let (rate, i) = contacts[slots]
                    .iter()
                    .enumerate()
                    .map(|(i, ce)| {
                        let v = sliding_velocity(kh, kj, ce).norm();
                        (sigma0 * v / cl.friction.stribeck(v), i)
                    })
                    .fold((0.0f64, 0), |a, b| if b.0 > a.0 { b } else { a });
                if h * rate > 2.0 {
                    guard.warned[ci] = true;
                    let name = cl.geometry.contact_names()[i];
                    out.push(Warning {
                        time: t,
                        message: format!(
                            "clearance joint '{}', contact '{name}': at t = {t} s its LuGre \
                             bristles relax at {rate:.3e} 1/s (sigma0 |v_t| / g), faster than \
                             the fixed step {h:e} s follows (h times the rate is {:.2}, above 2): \
                             use step = {:e} s or smaller, or integrator = \"ros34pw2\"",
                            cl.name,
                            h * rate,
                            suggested_step(2.0 / rate)
                        ),
                    });
                }
            }
            // An oil film is a spring and damper along the eccentricity at every state.
            if let (false, Some(film)) = (guard.warned[ci], &cl.film) {
                let s = cl.film_state(self.kin_of(cl.housing, ws), self.kin_of(cl.journal, ws));
                let (k, c, n) = s.linearised(film);
                let (inv0, blocks) = self.free_inverse_mass(cl, &n, (&s.rj, &s.rh), ws);
                let found = self.unstable_mode(
                    (&method, h),
                    (k.max(0.0), c.max(0.0)),
                    (inv0, &blocks),
                    ws,
                    (&mut guard.u, &mut guard.x),
                );
                if let Some(found) = found {
                    guard.warned[ci] = true;
                    out.push(unstable_warning(
                        t,
                        &format!("lubricated joint '{}', oil film", cl.name),
                        found,
                        &format!("film stiffness {k:.3e} N/m, damping {c:.3e} N s/m"),
                        &method,
                    ));
                }
            }
        }
    }
}

/// The step-size guard's warning for the unstable mode `(lambda, m, stable)` of `what` (a
/// stiffness and damping) at `who` (a contact or a film), at time `t`.
fn unstable_warning(
    t: f64,
    who: &str,
    (lambda, m, stable): ((f64, f64), f64, f64),
    what: &str,
    method: &Method,
) -> Warning {
    let mode = if lambda.1 != 0.0 {
        format!("{:.3e} +- {:.3e}i 1/s", lambda.0, lambda.1)
    } else {
        format!("{:.3e} 1/s", lambda.0)
    };
    Warning {
        time: t,
        message: format!(
            "{who}: at t = {t} s its {what} on an effective mass of {m:.3e} kg give the mode \
             {mode}, unstable for {} (largest stable step {stable:.3e} s): use step = {:e} s or \
             smaller, or integrator = \"dopri5\"",
            method.describe(),
            suggested_step(stable)
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suggested_steps_are_round() {
        for (h, want) in [(9.9e-5, 2e-5), (1.2e-4, 5e-5), (3e-6, 1e-6)] {
            let got = suggested_step(h);
            assert!((got / want - 1.0).abs() < 1e-12, "{h}: {got}");
        }
    }
}
