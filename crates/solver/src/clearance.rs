//! Joints with clearance: contact geometry and the force element that replaces a joint's
//! constraint rows (the 4-UPS/RPU paper, eqs. 1-47 and 59-62; geometry restated in the project's
//! docs, "Clearance joints").
//!
//! The housing (socket, bushing, bearing) is on the joint's `body_a` at `point_a` with axis
//! `axis_a`; the journal (ball, pin) is on `body_b` at `point_b` with axis `axis_b`. Every contact
//! gives a penetration `delta` (m, > 0 in contact), the unit direction `n` in which the journal
//! penetrates the housing, a contact point on each body and the penetration rate
//! `delta_dot = (v_journal - v_housing) . n` at the contact points (approach positive). The normal
//! force on the journal is `-F_N n`, on the housing `+F_N n`; friction opposes the tangential
//! relative velocity at the contact.
//!
//! * Spherical: e = r_ball - r_socket, delta = |e| - c, n = e/|e|; contact points r_ball + R_b n
//!   and r_socket + (R_b + c) n. With |e| <= c there is no contact and e is never normalised.
//! * Planar revolute: the same with e projected on the plane normal to the bearing axis; the
//!   joint keeps its three out-of-plane constraint rows (axes parallel, point in plane).
//! * Spatial revolute, radial contact at the bushing rims (P at s = +L_B/2, Q at s = -L_B/2):
//!   r_k = B_c + s_k e_B; the journal axis meets the rim plane at J_k = J_c + t e_J,
//!   t = ((r_k - J_c).e_B)/(e_J.e_B); the rim point towards which the journal leans is
//!   P_B = r_k + R_B1 unit(J_k - r_k); n = unit(perp(P_B - J_c, e_J)),
//!   delta = R_J - |perp(P_B - J_c, e_J)|. With parallel axes both rims see the same penetration:
//!   the line contact along the bushing is then carried by its two end points, as in the paper.
//!   When J_k = r_k (journal axis through the rim centre) that rim is not in contact.
//! * Spatial revolute, axial contact between shoulder and bushing end face (M on the +e_B face,
//!   N on the -e_B face): with sigma = +1 (M) or -1 (N), shoulder centre J_a = J_c +
//!   sigma (L_J/2) e_J, tilt direction u = perp(e_J, e_B), face point
//!   M_B = B_c + sigma (L_B/2) e_B + sigma R_B2 unit(u) (the face centre when the axes are
//!   parallel: face contact, no tilt moment), delta = sigma (M_B - J_a).e_J, n = -sigma e_J.
//!   Axial contact is simulated only when the scene gives an axial clearance; otherwise the joint
//!   keeps its axial constraint row.
//! * Planar translational (a slider in a guide; Flores, Leine and Glocker, Multibody Syst. Dyn.
//!   23 (2010) 165-190, with compliant contact at the corners): the slider is the rectangle of
//!   half-length a along its axis e_S and half-height b along its reference direction u_S,
//!   centred at the journal point J; the guide's faces are the planes at distance b + c from the
//!   housing point H along the guide's reference direction +-u_G. Corner k = (s_l, s_h) in
//!   {+-1}^2 is C_k = J + s_l a e_S + s_h b u_S, n = s_h u_G, delta = (C_k - H).n - (b + c): each
//!   corner meets the face on its own side, so free flight, one corner, two corners on one face
//!   and the crossed configuration (diagonal corners on opposite faces) are all the same four
//!   contacts. The guide is taken longer than the slider's stroke. The joint keeps three rows:
//!   the slider stays in the plane of e_G and u_G.
//! * Spatial translational (a box of half-width d along w_S = e_S x u_S in a channel): each of
//!   the eight corners C = J + s_l a e_S + s_h b u_S + s_w d w_S meets the face across it,
//!   n = s_h u_G, delta = (C - H).n - (b + c), and the face beside it, n = s_w w_G with
//!   w_G = e_G x u_G, delta = (C - H).n - (d + c): sixteen contacts, and no rows kept.

use nalgebra::Vector3;

use crate::contact::{FrictionLaw, NormalLaw};
use crate::film::Film;
use crate::kin::{Kin, any_normal};

/// Clearance geometry of one joint (lengths in m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Geometry {
    Spherical {
        ball_radius: f64,
        clearance: f64,
    },
    Planar {
        journal_radius: f64,
        bearing_radius: f64,
    },
    Revolute {
        journal_radius: f64,
        bushing_radius: f64,
        bushing_length: f64,
        face_radius: f64,
        /// L_J = L_B + 2 C_a when axial contact is simulated.
        journal_length: Option<f64>,
    },
    /// A slider in a guide: a rectangle of half-length `half_length` along the axis and
    /// half-height `half_height` across it (along the reference direction), between two parallel
    /// guide faces `clearance` away from it on each side when centred (planar); or, with
    /// `half_width`, a box of that half-width along the third direction in a channel with two
    /// more faces beside it, `clearance` away too (spatial).
    Translational {
        half_length: f64,
        half_height: f64,
        clearance: f64,
        half_width: Option<f64>,
    },
}

impl Geometry {
    /// Number of contact points evaluated.
    pub fn n_contacts(&self) -> usize {
        match self {
            Geometry::Spherical { .. } | Geometry::Planar { .. } => 1,
            Geometry::Revolute { journal_length, .. } => {
                if journal_length.is_some() {
                    4
                } else {
                    2
                }
            }
            Geometry::Translational { half_width, .. } => {
                if half_width.is_some() {
                    16
                } else {
                    4
                }
            }
        }
    }

    /// Names of the contacts, in output order.
    pub fn contact_names(&self) -> &'static [&'static str] {
        match self {
            Geometry::Spherical { .. } | Geometry::Planar { .. } => &["radial"],
            Geometry::Revolute { journal_length, .. } => {
                if journal_length.is_some() {
                    &["P", "Q", "M", "N"]
                } else {
                    &["P", "Q"]
                }
            }
            Geometry::Translational { half_width, .. } => {
                if half_width.is_some() {
                    &BOX_CONTACTS
                } else {
                    &CORNERS
                }
            }
        }
    }

    /// The divergence guard's default limit on penetration (m): one tenth of the journal (ball)
    /// radius, or of the slider's half-height. Elastic contact of metal parts penetrates micrometres; a penetration of this size
    /// means the contact law is far outside its validity and the integration is running away.
    pub fn runaway_penetration(&self) -> f64 {
        let r = match *self {
            Geometry::Spherical { ball_radius, .. } => ball_radius,
            Geometry::Planar { journal_radius, .. } | Geometry::Revolute { journal_radius, .. } => {
                journal_radius
            }
            Geometry::Translational { half_height, .. } => half_height,
        };
        0.1 * r
    }

    /// True for a journal in a bearing (planar or spatial), false for a ball in a socket.
    pub fn is_revolute(&self) -> bool {
        match self {
            Geometry::Spherical { .. } | Geometry::Translational { .. } => false,
            Geometry::Planar { .. } | Geometry::Revolute { .. } => true,
        }
    }

    /// True for a joint whose clearance lies normal to its axis (a journal in a bearing, a
    /// slider in a guide): an offset along the axis is no eccentricity.
    pub fn has_axis(&self) -> bool {
        match self {
            Geometry::Spherical { .. } => false,
            Geometry::Planar { .. }
            | Geometry::Revolute { .. }
            | Geometry::Translational { .. } => true,
        }
    }

    /// The radial clearance (m).
    pub fn radial_clearance(&self) -> f64 {
        match *self {
            Geometry::Spherical { clearance, .. } => clearance,
            Geometry::Planar {
                journal_radius,
                bearing_radius,
            } => bearing_radius - journal_radius,
            Geometry::Revolute {
                journal_radius,
                bushing_radius,
                ..
            } => bushing_radius - journal_radius,
            Geometry::Translational { clearance, .. } => clearance,
        }
    }

    pub fn describe(&self) -> String {
        match *self {
            Geometry::Spherical {
                ball_radius,
                clearance,
            } => format!("spherical, ball radius {ball_radius} m, clearance {clearance:e} m"),
            Geometry::Planar {
                journal_radius,
                bearing_radius,
            } => format!(
                "planar revolute, journal radius {journal_radius} m, bearing radius {bearing_radius} m (clearance {:.4e} m); contact: radial",
                bearing_radius - journal_radius
            ),
            Geometry::Revolute {
                journal_radius,
                bushing_radius,
                bushing_length,
                face_radius,
                journal_length,
            } => {
                let mut s = format!(
                    "spatial revolute, journal radius {journal_radius} m, bushing {bushing_radius} m x {bushing_length} m (radial clearance {:.4e} m); contacts: radial at rims P, Q",
                    bushing_radius - journal_radius
                );
                match journal_length {
                    Some(lj) => {
                        s += &format!(
                            ", axial at faces M, N (face radius {face_radius} m, axial clearance {:.4e} m)",
                            0.5 * (lj - bushing_length)
                        )
                    }
                    None => s += "; axial position held by a constraint row",
                }
                s
            }
            Geometry::Translational {
                half_length,
                half_height,
                clearance,
                half_width: None,
            } => format!(
                "planar translational, slider {} m long x {} m high, clearance {clearance:.4e} m per side; contacts: corners {}",
                2.0 * half_length,
                2.0 * half_height,
                CORNERS.join(", ")
            ),
            Geometry::Translational {
                half_length,
                half_height,
                clearance,
                half_width: Some(d),
            } => format!(
                "spatial translational, slider {} m long x {} m high x {} m wide in a channel, clearance {clearance:.4e} m per side; contacts: each of the 8 corners with the face above or below it (_on_upper, _on_lower) and beside it (_on_right, _on_left)",
                2.0 * half_length,
                2.0 * half_height,
                2.0 * d
            ),
        }
    }
}

/// The corners of a slider, in contact order: front (+axis) and rear, upper (+reference
/// direction) and lower.
const CORNERS: [&str; 4] = ["front_upper", "front_lower", "rear_upper", "rear_lower"];

/// The contacts of a box slider, in order: each corner (front and rear, upper and lower, right
/// (+axis x reference) and left) with the face across (above or below) and beside it.
const BOX_CONTACTS: [&str; 16] = [
    "front_upper_right_on_upper",
    "front_upper_right_on_right",
    "front_upper_left_on_upper",
    "front_upper_left_on_left",
    "front_lower_right_on_lower",
    "front_lower_right_on_right",
    "front_lower_left_on_lower",
    "front_lower_left_on_left",
    "rear_upper_right_on_upper",
    "rear_upper_right_on_right",
    "rear_upper_left_on_upper",
    "rear_upper_left_on_left",
    "rear_lower_right_on_lower",
    "rear_lower_right_on_right",
    "rear_lower_left_on_lower",
    "rear_lower_left_on_left",
];

/// A compiled clearance joint.
#[derive(Debug, Clone)]
pub struct Clearance {
    pub name: String,
    /// Index of the joint in the model's joint list.
    pub joint: usize,
    pub housing: usize,
    pub journal: usize,
    /// Housing and journal centres, COM-relative body axes (m).
    pub sh: Vector3<f64>,
    pub sj: Vector3<f64>,
    /// Unit axes in body axes (unused for spherical).
    pub axis_h: Vector3<f64>,
    pub axis_j: Vector3<f64>,
    /// Unit reference directions normal to the axes, body axes: across a slider (its height)
    /// and across its guide (the faces' normal); the joint's `reference_a`, `reference_b`.
    pub ref_h: Vector3<f64>,
    pub ref_j: Vector3<f64>,
    pub geometry: Geometry,
    pub law: NormalLaw,
    pub friction: FrictionLaw,
    /// The oil film of a lubricated journal bearing ([`crate::film`]).
    pub film: Option<Film>,
    /// First slot of this joint's contacts in the workspace contact arrays.
    pub first: usize,
    /// With LuGre friction: the first of this joint's bristle states in the model's bristle
    /// array (3 per contact, housing body axes; see [`crate::model::Model::n_bristle`]).
    pub bristle: Option<usize>,
}

/// The state of one contact at one evaluation.
#[derive(Debug, Clone, Copy, Default)]
pub struct ContactEval {
    /// Penetration (m); negative: gap.
    pub delta: f64,
    /// Penetration rate (m/s), approach positive.
    pub delta_dot: f64,
    /// Direction in which the journal penetrates (unit, global; zero when undefined).
    pub n: Vector3<f64>,
    /// Contact points on journal and housing (global, m).
    pub pj: Vector3<f64>,
    pub ph: Vector3<f64>,
    /// Normal force magnitude (N) and friction force on the journal (N, global).
    pub fn_: f64,
    pub ft: Vector3<f64>,
}

impl ContactEval {
    pub fn active(&self) -> bool {
        self.delta > 0.0 && self.fn_ > 0.0
    }
}

/// Resultant of a clearance joint's contacts, about each body's centre of mass.
#[derive(Debug, Clone, Copy, Default)]
pub struct Resultant {
    pub force_j: Vector3<f64>,
    pub moment_j: Vector3<f64>,
    pub force_h: Vector3<f64>,
    pub moment_h: Vector3<f64>,
}

#[inline]
fn perp(v: &Vector3<f64>, a: &Vector3<f64>) -> Vector3<f64> {
    v - a * v.dot(a)
}

#[inline]
fn vel(k: &Kin, p: &Vector3<f64>) -> Vector3<f64> {
    k.v + k.w.cross(&(p - k.r))
}

impl Clearance {
    /// Orthonormal directions (u, w) normal to the housing axis, housing axes: the plane in which
    /// the journal-centre orbit is drawn (for a spherical joint, the housing's x-y plane).
    pub fn radial_axes(&self) -> (Vector3<f64>, Vector3<f64>) {
        let a = match self.geometry {
            Geometry::Spherical { .. } => Vector3::z(),
            Geometry::Planar { .. } | Geometry::Revolute { .. } => self.axis_h,
            // Across the guide (the reference direction) and out of the slider's plane.
            Geometry::Translational { .. } => return (self.ref_h, self.axis_h.cross(&self.ref_h)),
        };
        let u = any_normal(&a);
        (u, a.cross(&u))
    }

    /// Eccentricity of the journal centre from the housing centre, global (m).
    pub fn eccentricity(&self, kh: &Kin, kj: &Kin) -> Vector3<f64> {
        (kj.r + kj.rot * self.sj) - (kh.r + kh.rot * self.sh)
    }

    /// Spatial revolute only: where the journal axis crosses the planes of the two bushing rims
    /// (s = +L_B/2, the P side, and s = -L_B/2, the Q side), as (u, w) components in the housing's
    /// radial axes (m): the orbits of both journal ends. `None` for other geometries. When the
    /// journal axis lies in a rim plane (a 90-degree tilt, far outside any clearance) it meets
    /// neither, and both ends report the centre's offset.
    pub fn end_offsets(&self, kh: &Kin, kj: &Kin) -> Option<[[f64; 2]; 2]> {
        let Geometry::Revolute {
            bushing_length: lb, ..
        } = self.geometry
        else {
            return None;
        };
        let el = kh.rot.transpose() * self.eccentricity(kh, kj);
        let aj = kh.rot.transpose() * (kj.rot * self.axis_j);
        let ah = self.axis_h;
        let c = aj.dot(&ah);
        let (u, w) = self.radial_axes();
        let at = |s: f64| {
            let p = if c.abs() < 1e-9 {
                el
            } else {
                el + aj * ((s - el.dot(&ah)) / c)
            };
            [p.dot(&u), p.dot(&w)]
        };
        Some([at(0.5 * lb), at(-0.5 * lb)])
    }

    /// Contact geometry (delta, delta_dot, n, points) of every contact into `out`.
    pub fn geometry(&self, kh: &Kin, kj: &Kin, out: &mut [ContactEval]) {
        let rh = kh.r + kh.rot * self.sh;
        let rj = kj.r + kj.rot * self.sj;
        match self.geometry {
            Geometry::Spherical {
                ball_radius,
                clearance,
            } => {
                let e = rj - rh;
                out[0] = radial(e, clearance, ball_radius, rh, rj, kh, kj);
            }
            Geometry::Planar {
                journal_radius,
                bearing_radius,
            } => {
                let a = kh.rot * self.axis_h;
                let e = perp(&(rj - rh), &a);
                out[0] = radial(
                    e,
                    bearing_radius - journal_radius,
                    journal_radius,
                    rh,
                    rj,
                    kh,
                    kj,
                );
            }
            Geometry::Revolute {
                journal_radius: rj_rad,
                bushing_radius: rb1,
                bushing_length: lb,
                face_radius: rb2,
                journal_length,
            } => {
                let eb = kh.rot * self.axis_h;
                let ej = kj.rot * self.axis_j;
                let denom = ej.dot(&eb);
                for (k, s) in [0.5 * lb, -0.5 * lb].into_iter().enumerate() {
                    let rk = rh + eb * s;
                    let mut c = ContactEval {
                        delta: rj_rad - rb1,
                        ..Default::default()
                    };
                    if denom.abs() > 1e-9 {
                        let t = (rk - rj).dot(&eb) / denom;
                        let dk = rj + ej * t - rk;
                        let dn = dk.norm();
                        if dn > 1e-14 * rb1 {
                            let pb = rk + dk * (rb1 / dn);
                            let q = pb - rj;
                            let qp = perp(&q, &ej);
                            let qn = qp.norm();
                            let n = qp / qn;
                            let pj = rj + ej * q.dot(&ej) + n * rj_rad;
                            c = ContactEval {
                                delta: rj_rad - qn,
                                delta_dot: (vel(kj, &pj) - vel(kh, &pb)).dot(&n),
                                n,
                                pj,
                                ph: pb,
                                ..Default::default()
                            };
                        }
                    }
                    out[k] = c;
                }
                if let Some(lj) = journal_length {
                    let u = perp(&ej, &eb);
                    let un = u.norm();
                    let uhat = if un > 1e-12 { u / un } else { Vector3::zeros() };
                    for (k, sigma) in [1.0, -1.0].into_iter().enumerate() {
                        let ja = rj + ej * (0.5 * lj * sigma);
                        let mb = rh + eb * (0.5 * lb * sigma) + uhat * (rb2 * sigma);
                        let n = -ej * sigma;
                        out[2 + k] = ContactEval {
                            delta: sigma * (mb - ja).dot(&ej),
                            delta_dot: (vel(kj, &mb) - vel(kh, &mb)).dot(&n),
                            n,
                            pj: mb,
                            ph: mb,
                            ..Default::default()
                        };
                    }
                }
            }
            Geometry::Translational {
                half_length,
                half_height,
                clearance,
                half_width,
            } => {
                let (up, bx, bu) = (
                    kh.rot * self.ref_h,
                    kj.rot * self.axis_j,
                    kj.rot * self.ref_j,
                );
                let (side, bw) = (kh.rot * self.axis_h.cross(&self.ref_h), bx.cross(&bu));
                let contact = |pj: Vector3<f64>, n: Vector3<f64>, wall: f64| {
                    let delta = (pj - rh).dot(&n) - wall;
                    let ph = pj - n * delta;
                    ContactEval {
                        delta,
                        delta_dot: (vel(kj, &pj) - vel(kh, &ph)).dot(&n),
                        n,
                        pj,
                        ph,
                        ..Default::default()
                    }
                };
                let mut k = 0;
                for sl in [1.0, -1.0] {
                    for sh in [1.0, -1.0] {
                        let mid = rj + bx * (sl * half_length) + bu * (sh * half_height);
                        let Some(d) = half_width else {
                            out[k] = contact(mid, up * sh, half_height + clearance);
                            k += 1;
                            continue;
                        };
                        for sw in [1.0, -1.0] {
                            let corner = mid + bw * (sw * d);
                            out[k] = contact(corner, up * sh, half_height + clearance);
                            out[k + 1] = contact(corner, side * sw, d + clearance);
                            k += 2;
                        }
                    }
                }
            }
        }
    }

    /// The sliding speed |v_t| (m/s) of each contact (geometry already in `contacts`): the
    /// speed the friction law reads.
    pub fn sliding_speeds(&self, kh: &Kin, kj: &Kin, contacts: &[ContactEval], out: &mut [f64]) {
        for (c, v) in contacts.iter().zip(out) {
            *v = sliding_velocity(kh, kj, c).norm();
        }
    }

    /// Normal and friction forces of the contacts (geometry already in `out`), with the onset
    /// velocities `onset` (NaN: the contact began inside the current step, use delta_dot), and
    /// their resultant on both bodies. With LuGre friction, `bristle` holds the contacts'
    /// deflections (3 each, housing body axes, m) and their rates (the rate of change seen from
    /// the housing) are written into `rate`, in and out of contact: the
    /// bristles follow the sliding velocity at the nearest points at all times, so their state
    /// is continuous and smooth through an onset (empty slices for the other laws).
    pub fn forces(
        &self,
        (kh, kj): (&Kin, &Kin),
        onset: &[f64],
        (bristle, rate): (&[f64], &mut [f64]),
        out: &mut [ContactEval],
    ) -> Resultant {
        let mut r = Resultant::default();
        let lugre = self.friction.has_bristles();
        for (i, (c, &v_on)) in out.iter_mut().zip(onset).enumerate() {
            c.fn_ = 0.0;
            c.ft = Vector3::zeros();
            // LuGre: the deflection is held in the housing's axes, so that bristles stuck to a
            // turning housing turn with it; its rate there, and the tangential parts of both
            // (global) for the force. Where the geometry leaves the contact undefined (a
            // centred journal, no normal) the bristles rest.
            let bristles = lugre.then(|| {
                let vt = if c.n.norm_squared() > 0.5 {
                    sliding_velocity(kh, kj, c)
                } else {
                    Vector3::zeros()
                };
                let z = kh.rot * Vector3::from_column_slice(&bristle[3 * i..3 * i + 3]);
                let zd = self.friction.bristle_rate(&z, &vt);
                let zd_h = kh.rot.transpose() * zd;
                rate[3 * i..3 * i + 3].copy_from_slice(zd_h.as_slice());
                (perp(&z, &c.n), perp(&zd, &c.n), vt)
            });
            if c.delta <= 0.0 {
                continue;
            }
            let v_on = if v_on.is_nan() { c.delta_dot } else { v_on };
            let fn_ = self.law.force(c.delta, c.delta_dot, v_on);
            if fn_ <= 0.0 {
                continue;
            }
            c.fn_ = fn_;
            let mut f = -c.n * fn_;
            if let Some((zt, zt_dot, vt)) = bristles {
                c.ft = self.friction.bristle_force(&zt, &zt_dot, &vt, fn_);
                f += c.ft;
            } else if !self.friction.is_none() {
                let vt = sliding_velocity(kh, kj, c);
                let v = vt.norm();
                if v > 0.0 {
                    c.ft = -vt * (self.friction.coefficient(v) * fn_ / v);
                    f += c.ft;
                }
            }
            r.force_j += f;
            r.moment_j += (c.pj - kj.r).cross(&f);
            r.force_h -= f;
            r.moment_h -= (c.ph - kh.r).cross(&f);
        }
        if let Some(film) = &self.film {
            // The pressure's resultant passes through the journal centre; the bearing takes the
            // opposite force on the same line, so the pair has no moment (the viscous shear that
            // would balance a moment between the two centres is not modelled).
            let s = self.film_state(kh, kj);
            let f = s.force(film);
            r.force_j += f;
            r.moment_j += (s.rj - kj.r).cross(&f);
            r.force_h -= f;
            r.moment_h -= (s.rj - kh.r).cross(&f);
        }
        r
    }

    /// What a film acts on: the journal centre's eccentricity and its rate in the plane normal
    /// to the housing axis, and the two bodies' spins about that axis.
    pub fn film_state(&self, kh: &Kin, kj: &Kin) -> FilmState {
        let a = kh.rot * self.axis_h;
        let (rh, rj) = (kh.r + kh.rot * self.sh, kj.r + kj.rot * self.sj);
        FilmState {
            e: perp(&(rj - rh), &a),
            e_dot: perp(&(vel(kj, &rj) - vel(kh, &rh)), &a),
            spin: (kj.w + kh.w).dot(&a),
            a,
            rj,
            rh,
        }
    }

    /// The film force on the journal (N, global), applied at the journal centre (the bearing
    /// takes the opposite force on the same line).
    pub fn film_force(&self, film: &Film, kh: &Kin, kj: &Kin) -> Vector3<f64> {
        self.film_state(kh, kj).force(film)
    }
}

/// A lubricated joint's film kinematics ([`Clearance::film_state`]), global axes.
#[derive(Debug, Clone, Copy)]
pub struct FilmState {
    /// Journal and housing centres (m).
    pub rj: Vector3<f64>,
    pub rh: Vector3<f64>,
    /// The unit housing axis.
    pub a: Vector3<f64>,
    /// Eccentricity of the journal centre normal to `a` (m) and its rate (m/s).
    pub e: Vector3<f64>,
    pub e_dot: Vector3<f64>,
    /// The journal's and the housing's spins about `a`, summed (rad/s).
    pub spin: f64,
}

impl FilmState {
    /// The force of `film` on the journal in this state (N, global).
    pub fn force(&self, film: &Film) -> Vector3<f64> {
        film.force(&self.e, &self.e_dot, &self.a, self.spin)
    }

    /// The film's stiffness and damping along the eccentricity, with its direction
    /// ([`Film::linearised`]).
    pub fn linearised(&self, film: &Film) -> (f64, f64, Vector3<f64>) {
        film.linearised(&self.e, &self.e_dot, &self.a, self.spin)
    }
}

/// The journal's velocity relative to the housing at a contact, in the contact's tangent plane
/// (m/s): what the friction law reads, and what the friction events compare with its kinks.
#[inline]
pub(crate) fn sliding_velocity(kh: &Kin, kj: &Kin, c: &ContactEval) -> Vector3<f64> {
    perp(&(vel(kj, &c.pj) - vel(kh, &c.ph)), &c.n)
}

/// A radial (sphere-in-socket or circle-in-circle) contact from the eccentricity `e`.
fn radial(
    e: Vector3<f64>,
    clearance: f64,
    inner_radius: f64,
    rh: Vector3<f64>,
    rj: Vector3<f64>,
    kh: &Kin,
    kj: &Kin,
) -> ContactEval {
    let d = e.norm();
    // The clearance is positive, so contact needs |e| > c > 0 and n is always defined there;
    // below, n is only used for the rate, and only when |e| is not tiny.
    if d <= 1e-14 * inner_radius.max(clearance) {
        return ContactEval {
            delta: d - clearance,
            ..Default::default()
        };
    }
    let n = e / d;
    let pj = rj + n * inner_radius;
    let ph = rh + n * (inner_radius + clearance);
    ContactEval {
        delta: d - clearance,
        delta_dot: (vel(kj, &rj) - vel(kh, &rh)).dot(&n),
        n,
        pj,
        ph,
        ..Default::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::{Elastic, NormalLaw};
    use nalgebra::{Matrix3, Rotation3};

    fn kin(r: Vector3<f64>, rot: Matrix3<f64>) -> Kin {
        Kin {
            r,
            rot,
            v: Vector3::zeros(),
            w: Vector3::zeros(),
        }
    }

    // The paper's R1: R_J = 9.7 mm, R_B1 = 10 mm, L_B = 180 mm, R_B2 = 14 mm, C_a = 0.3 mm.
    const RJ: f64 = 0.0097;
    const RB1: f64 = 0.010;
    const LB: f64 = 0.180;
    const RB2: f64 = 0.014;
    const CA: f64 = 0.0003;

    fn revolute() -> Clearance {
        Clearance {
            name: "R1".into(),
            joint: 0,
            housing: 0,
            journal: 1,
            sh: Vector3::zeros(),
            sj: Vector3::zeros(),
            axis_h: Vector3::z(),
            axis_j: Vector3::z(),
            geometry: Geometry::Revolute {
                journal_radius: RJ,
                bushing_radius: RB1,
                bushing_length: LB,
                face_radius: RB2,
                journal_length: Some(LB + 2.0 * CA),
            },
            law: NormalLaw::Hertz {
                el: Elastic::Power { k: 8.62e10, n: 1.5 },
            },
            friction: FrictionLaw::None,
            film: None,
            ref_h: Vector3::x(),
            ref_j: Vector3::x(),
            first: 0,
            bristle: None,
        }
    }

    fn eval(c: &Clearance, kj: Kin) -> [ContactEval; 4] {
        let mut out = [ContactEval::default(); 4];
        c.geometry(&kin(Vector3::zeros(), Matrix3::identity()), &kj, &mut out);
        out
    }

    #[test]
    fn parallel_shift_gives_u_minus_cr_at_both_rims() {
        let u = 0.0005;
        let out = eval(
            &revolute(),
            kin(Vector3::new(u, 0.0, 0.0), Matrix3::identity()),
        );
        for c in &out[..2] {
            // Exact up to rounding of lengths of order 1e-2 m.
            assert!((c.delta - (u - (RB1 - RJ))).abs() < 1e-15, "{}", c.delta);
            assert!((c.n - Vector3::x()).norm() < 1e-12);
        }
        // No axial penetration without an axial shift.
        assert!((out[2].delta + CA).abs() < 1e-15 && (out[3].delta + CA).abs() < 1e-15);
    }

    #[test]
    fn tilt_gives_the_rim_formula_on_opposite_sides() {
        let phi = 0.004;
        let rot = *Rotation3::from_axis_angle(&Vector3::y_axis(), phi).matrix();
        let out = eval(&revolute(), kin(Vector3::zeros(), rot));
        let exact = RJ - (RB1 * phi.cos() - 0.5 * LB * phi.sin());
        for c in &out[..2] {
            // The notes' formula holds to O(phi^2 R) ~ 1e-7 relative corrections; the geometry
            // here is exact, so compare at 1e-9 m (penetrations are ~4e-5 m).
            assert!((c.delta - exact).abs() < 1e-9, "{} vs {exact}", c.delta);
        }
        assert!(
            out[0].n.dot(&out[1].n) < -0.99,
            "rim contacts on opposite sides"
        );
        assert!((exact - (0.5 * LB * phi - (RB1 - RJ))).abs() < 2e-7);
    }

    #[test]
    fn axial_shift_and_tilt_give_the_face_formulas() {
        let w = 0.0005;
        let out = eval(
            &revolute(),
            kin(Vector3::new(0.0, 0.0, -w), Matrix3::identity()),
        );
        assert!((out[2].delta - (w - CA)).abs() < 1e-15, "{}", out[2].delta);
        assert!((out[3].delta - (-w - CA)).abs() < 1e-15);
        let phi = 0.03;
        let rot = *Rotation3::from_axis_angle(&Vector3::y_axis(), phi).matrix();
        let out = eval(&revolute(), kin(Vector3::zeros(), rot));
        let exact = RB2 * phi.sin() + 0.5 * LB * phi.cos() - 0.5 * (LB + 2.0 * CA);
        assert!((out[2].delta - exact).abs() < 1e-15 && (out[3].delta - exact).abs() < 1e-15);
    }

    #[test]
    fn degenerate_configurations_give_finite_forces() {
        let mut c = revolute();
        c.law = NormalLaw::Hertz {
            el: Elastic::Power { k: 8.62e10, n: 1.5 },
        };
        c.friction = FrictionLaw::Coulomb {
            mu: 0.1,
            v_reg: 1e-3,
        };
        let onset = [f64::NAN; 4];
        let cases = [
            // concentric, coincident axes
            kin(Vector3::zeros(), Matrix3::identity()),
            // axes parallel, in radial and axial contact at once
            kin(Vector3::new(0.001, 0.0, 0.001), Matrix3::identity()),
            // journal perpendicular to the bushing
            kin(
                Vector3::zeros(),
                *Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2)
                    .matrix(),
            ),
            // journal axis through a rim centre
            kin(
                Vector3::new(0.0, 0.0, 0.0),
                *Rotation3::from_axis_angle(&Vector3::x_axis(), 1e-3).matrix(),
            ),
        ];
        for kj in cases {
            let mut out = [ContactEval::default(); 4];
            let kh = kin(Vector3::zeros(), Matrix3::identity());
            c.geometry(&kh, &kj, &mut out);
            let r = c.forces((&kh, &kj), &onset, (&[], &mut []), &mut out);
            for v in [r.force_j, r.moment_j, r.force_h, r.moment_h] {
                assert!(v.iter().all(|x| x.is_finite()), "{kj:?}: {r:?}");
            }
            for o in &out {
                assert!(o.delta.is_finite() && o.delta_dot.is_finite() && o.fn_.is_finite());
            }
        }
        // Spherical, exactly concentric: no contact, no NaN.
        let s = Clearance {
            geometry: Geometry::Spherical {
                ball_radius: 0.015,
                clearance: 3e-4,
            },
            ..revolute()
        };
        let mut out = [ContactEval::default(); 1];
        let k0 = kin(Vector3::zeros(), Matrix3::identity());
        s.geometry(&k0, &k0, &mut out);
        let r = s.forces((&k0, &k0), &onset[..1], (&[], &mut []), &mut out);
        assert_eq!(out[0].delta, -3e-4);
        assert_eq!(r.force_j, Vector3::zeros());
    }

    /// A ball stuck in its socket while both turn together about z: the bristles' deflection,
    /// held in the housing's axes, turns with them, so the friction force seen from the housing
    /// is the same at every angle (held in global axes it would shrink as the contact normal
    /// turns away from it, and vanish after a quarter turn).
    #[test]
    fn lugre_bristles_turn_with_the_housing() {
        let c = Clearance {
            geometry: Geometry::Spherical {
                ball_radius: 0.015,
                clearance: 3e-4,
            },
            law: NormalLaw::Hertz {
                el: Elastic::Power { k: 1e10, n: 1.5 },
            },
            friction: FrictionLaw::LuGre {
                mu_c: 0.1,
                mu_s: 0.15,
                v_s: 1e-3,
                sigma0: 1e5,
                sigma1: 0.0,
                sigma2: 0.0,
            },
            bristle: Some(0),
            ..revolute()
        };
        // In the housing's axes: the ball 10 um into the wall along x, the bristles deflected
        // 1 um along y (tangent to the wall there).
        let (e_h, z_h) = (Vector3::new(3.1e-4, 0.0, 0.0), [0.0, 1e-6, 0.0]);
        let w = Vector3::new(0.0, 0.0, 2.0);
        let mut seen = Vec::new();
        for angle in [0.0, 0.7, std::f64::consts::FRAC_PI_2, 2.5] {
            let rot = *nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), angle).matrix();
            let kh = Kin {
                r: Vector3::zeros(),
                rot,
                v: Vector3::zeros(),
                w,
            };
            let r = rot * e_h;
            let kj = Kin {
                r,
                rot,
                v: w.cross(&r),
                w,
            };
            let mut out = [ContactEval::default(); 1];
            c.geometry(&kh, &kj, &mut out);
            let mut rate = [0.0; 3];
            c.forces((&kh, &kj), &[f64::NAN], (&z_h, &mut rate), &mut out);
            // The bristles' rate (in the housing's axes: what the co-rotating contact's points,
            // a penetration apart, slide by, omega delta) and the force in the housing's axes.
            seen.push((Vector3::from(rate), rot.transpose() * out[0].ft));
        }
        let (r0, f0) = seen[0];
        // The spring sigma0 z F_N: no damping terms here (sigma1 = sigma2 = 0).
        let spring = -1e5 * 1e-6 * 1e10 * (1e-5f64).powf(1.5);
        assert!(
            (f0.y / spring - 1.0).abs() < 1e-9 && f0.x.abs() < 1e-12 * f0.y.abs(),
            "{f0:?}"
        );
        for (r, f) in &seen {
            assert!((r - r0).norm() <= 1e-12 * r0.norm(), "{r:?} against {r0:?}");
            assert!((f - f0).norm() <= 1e-12 * f0.norm(), "{f:?} against {f0:?}");
        }
    }
}
