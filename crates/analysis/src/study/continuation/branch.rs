//! What a continuation reports while it runs ([`Report`]) and the summary lines printed from
//! what it found (the data, [`Continuation`] and its branches, are in
//! [`crate::storage::branches`], which writes and reads them).

use crate::storage::branches::Continuation;

/// What the continuation reports after every point it adds.
pub struct Report {
    /// The fraction done (by points, against `max_branches * max_points`).
    pub fraction: f64,
    /// One line on the point just added.
    pub line: String,
    /// Everything so far, marked unfinished: written as a checkpoint it can be resumed.
    pub snapshot: Continuation,
}

/// Lines for the terminal: each branch and each special point.
pub fn summary(c: &Continuation) -> Vec<String> {
    let mut out = Vec::new();
    for (i, b) in c.branches.iter().enumerate() {
        let (Some(a), Some(z)) = (b.points.first(), b.points.last()) else {
            out.push(format!(
                "branch {i}      period {}, from {}: no point ({})",
                b.k, b.origin, b.end
            ));
            continue;
        };
        let stable = b.points.iter().filter(|p| p.orbit.stable()).count();
        out.push(format!(
            "branch {i}      period {}, {} points from {} to {} ({stable} stable), from {}; ended: {}",
            b.k,
            b.points.len(),
            a.parameter,
            z.parameter,
            b.origin,
            b.end
        ));
    }
    for s in &c.specials {
        out.push(format!(
            "special      {} on branch {} at {} (within {:.1e})",
            s.kind.name(),
            s.branch,
            s.parameter,
            s.bracket
        ));
    }
    out.push(format!("continuation {:.3} s", c.wall));
    out
}
