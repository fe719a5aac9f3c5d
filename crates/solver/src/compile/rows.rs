//! The constraint rows the passes append to ([`Rows`]) and a joint's frame ([`JointFrame`]), from
//! which the primitives of the joint rows (pass 3), of the rows a clearance element leaves to its
//! joint (pass 4) and of the drive rows (pass 5) are built. A leaf shared by those passes.

use nalgebra::Vector3;

use crate::model::Prim;

/// The constraint primitives and the number of rows so far.
#[derive(Default)]
pub(crate) struct Rows {
    /// Each primitive with its first row.
    pub prims: Vec<(Prim, usize)>,
    pub n: usize,
}

impl Rows {
    /// Appends `p` after the rows so far.
    pub fn push(&mut self, p: Prim) {
        let n = p.rows();
        self.prims.push((p, self.n));
        self.n += n;
    }
}

/// A joint's bodies, points (COM-relative, body axes) and frame: (u_a, w_a, axis_a) orthonormal
/// on body a, axis_b and the reference direction u_b on body b. The primitives of every joint
/// row and drive row are built from it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct JointFrame {
    pub a: usize,
    pub b: usize,
    pub sa: Vector3<f64>,
    pub sb: Vector3<f64>,
    pub axis_a: Vector3<f64>,
    pub axis_b: Vector3<f64>,
    pub ua: Vector3<f64>,
    pub wa: Vector3<f64>,
    pub ub: Vector3<f64>,
}

impl JointFrame {
    /// P_b = P_a (3 rows).
    pub fn coincident(&self) -> Prim {
        let JointFrame { a, sa, b, sb, .. } = *self;
        Prim::Coincident { a, sa, b, sb }
    }

    /// axis_b normal to u_a and to w_a: the axes stay parallel (2 rows).
    pub fn parallel(&self) -> [Prim; 2] {
        let JointFrame { a, b, axis_b, .. } = *self;
        [self.ua, self.wa].map(|u| Prim::Perpendicular { a, u, b, v: axis_b })
    }

    /// d = P_b - P_a normal to u_a and to w_a: the points stay on axis_a (2 rows).
    pub fn collinear(&self) -> [Prim; 2] {
        let JointFrame { a, sa, b, sb, .. } = *self;
        [self.ua, self.wa].map(|u| Prim::Distance {
            a,
            u,
            sa,
            b,
            sb,
            drive: None,
        })
    }

    /// w_a . u_b = 0: no rotation about the axis (1 row).
    pub fn lock(&self) -> Prim {
        let JointFrame { a, wa, b, ub, .. } = *self;
        Prim::Perpendicular { a, u: wa, b, v: ub }
    }

    /// d . axis_a = s(t), with s = 0 without a drive (1 row).
    pub fn along_axis(&self, drive: Option<usize>) -> Prim {
        let JointFrame {
            a,
            axis_a,
            sa,
            b,
            sb,
            ..
        } = *self;
        Prim::Distance {
            a,
            u: axis_a,
            sa,
            b,
            sb,
            drive,
        }
    }

    /// theta = s(t), theta the angle of u_b from u_a about axis_a (1 row).
    pub fn angle(&self, drive: usize) -> Prim {
        let JointFrame {
            a,
            axis_a,
            ua,
            wa,
            b,
            ub,
            ..
        } = *self;
        Prim::Angle {
            a,
            axis: axis_a,
            ua,
            wa,
            b,
            ub,
            drive,
        }
    }
}
