//! Small helpers over the 6-vector blocks (translation, rotation) of the stages: a leaf, so that
//! every stage can use them without importing another.

use nalgebra::Vector3;

#[inline]
pub(super) fn v3(s: &[f64]) -> Vector3<f64> {
    Vector3::new(s[0], s[1], s[2])
}

#[inline]
pub(super) fn dot6(a: &[f64; 6], b: &[f64; 6]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] + a[4] * b[4] + a[5] * b[5]
}

/// [`dot6`] of blocks one of which has a zero translational half: the rotational halves only
/// (equal to [`dot6`] up to the sign of a zero result, since the skipped products are zeros).
#[inline]
pub(super) fn dot3w(a: &[f64; 6], b: &[f64; 6]) -> f64 {
    a[3] * b[3] + a[4] * b[4] + a[5] * b[5]
}

#[inline]
pub(super) fn block(v: &Vector3<f64>, w: &Vector3<f64>) -> [f64; 6] {
    [v.x, v.y, v.z, w.x, w.y, w.z]
}
