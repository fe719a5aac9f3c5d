//! The order in which a parallel sweep runs its values: costliest first, by an estimate learnt
//! from the values already run.
//!
//! A sweep's values can differ several times in cost (on the 4-UPS/RPU the smallest clearance
//! takes 2.2 times the evaluations of the largest), and the sweep ends when its last value does.
//! With `p` threads each taking the next value when it is free (list scheduling), running the
//! values in order of decreasing cost (Graham's LPT rule) bounds the sweep's wall time by
//! `4/3 - 1/(3p)` times the best schedule's (Graham 1969, "Bounds on multiprocessing timing
//! anomalies", SIAM J. Appl. Math. 17(2)); in an arbitrary order the bound is `2 - 1/p`.
//!
//! The costs are not known before the values run, so [`Queue`] estimates them from the values
//! already run (measured in this run, or read from the file a resumed sweep goes on with): the
//! cost `c(x)` of a value `x` not yet run is interpolated linearly in the swept parameter
//! between the nearest finished values on either side of it, and extrapolated along the line
//! through the two nearest finished values (never below zero) beyond the last one on one side.
//! Costs usually vary smoothly with the parameter (a clearance, a stiffness, a drive speed), so
//! the estimate improves as the sweep runs. Until a value has finished the values go in the
//! order listed; equal estimates go to the value listed first. Sweeps of more than 4096 values
//! go in the listed order throughout (a pick by estimate costs O(n log n) for n values).
//!
//! Simulated with two threads (the unit tests use the same model): on the measured job times of
//! the section-3 diagram (40 values, costs falling 2.2 times along the list) this order and the
//! listed order both end within 1.5 % of the ideal, the summed cost over the threads. Where the
//! costliest values sit elsewhere this order gains: 41.0 against 43.0 for a cost peaked in the
//! middle of 9 values, 51.0 against 54.0 for one highest at both ends. On costs rising along the
//! list the gain is small or none (the first values must finish before the trend is known).
//! Costs with no trend in the parameter cannot be predicted, and no order helps them reliably.
//! The simulations are checks of this rule, not bounds: Graham's bound holds for exact costs.
//!
//! The order changes only when the values run, never what they compute: each value is an
//! independent run written to its own row.

/// Sweeps of more values than this go in the listed order: a pick by estimate costs
/// O(n log n), and with values this many and this fine the order hardly matters.
const LEARNED_UP_TO: usize = 4096;

/// The values of a sweep still to run and the costs (s) of those already run.
#[derive(Debug, Clone)]
pub struct Queue {
    /// Parameter value of each job.
    param: Vec<f64>,
    /// Measured cost of each finished job.
    cost: Vec<Option<f64>>,
    /// Whether each job has been handed out (or needs no run).
    taken: Vec<bool>,
    /// No job listed before this one is left (used beyond [`LEARNED_UP_TO`] values).
    next_listed: usize,
}

impl Queue {
    /// A queue of the jobs with parameter values `param`, of which those with `pending[i]`
    /// false need no run; `known[i]` is a cost already measured for job `i` (on resume, from
    /// the file), which the estimate uses.
    pub fn new(param: Vec<f64>, pending: &[bool], known: &[Option<f64>]) -> Queue {
        let n = param.len();
        assert_eq!(pending.len(), n);
        assert_eq!(known.len(), n);
        Queue {
            param,
            cost: known
                .iter()
                .map(|c| c.filter(|c| c.is_finite() && *c >= 0.0))
                .collect(),
            taken: pending.iter().map(|p| !p).collect(),
            next_listed: 0,
        }
    }

    /// Records that job `i` took `cost` (s).
    pub fn finished(&mut self, i: usize, cost: f64) {
        if cost.is_finite() && cost >= 0.0 {
            self.cost[i] = Some(cost);
        }
    }

    /// The finished jobs as (parameter, cost), sorted by parameter.
    fn known(&self) -> Vec<(f64, f64)> {
        let mut known: Vec<(f64, f64)> = self
            .cost
            .iter()
            .zip(&self.param)
            .filter_map(|(c, &p)| c.map(|c| (p, c)))
            .collect();
        known.sort_by(|a, b| a.0.total_cmp(&b.0));
        known
    }

    /// The estimated cost of job `i` from the finished jobs, None when none has finished.
    pub fn estimate(&self, i: usize) -> Option<f64> {
        estimate(&self.known(), self.param[i])
    }

    /// The next job to run, None when every job has been handed out.
    pub fn take_next(&mut self) -> Option<usize> {
        if self.param.len() > LEARNED_UP_TO {
            while self.next_listed < self.taken.len() && self.taken[self.next_listed] {
                self.next_listed += 1;
            }
            let pick = self.next_listed;
            *self.taken.get_mut(pick)? = true;
            return Some(pick);
        }
        // Sorted once per pick: a pick costs O(n log n) with n values.
        let known = self.known();
        let mut best: Option<(usize, f64)> = None;
        for i in (0..self.param.len()).filter(|&i| !self.taken[i]) {
            // Nothing learnt yet: every estimate is equal, so the first listed goes first.
            let c = estimate(&known, self.param[i]).unwrap_or(0.0);
            if best.is_none_or(|(_, b)| c > b) {
                best = Some((i, c));
            }
        }
        let (pick, _) = best?;
        self.taken[pick] = true;
        Some(pick)
    }
}

/// The cost at parameter `x` from the finished values `known` (sorted by parameter): linear
/// between the nearest on either side, along the nearest two beyond them (never below zero).
fn estimate(known: &[(f64, f64)], x: f64) -> Option<f64> {
    let split = known.partition_point(|&(p, _)| p <= x);
    let ((p0, c0), (p1, c1)) = match (split, known.len()) {
        (_, 0) => return None,
        (_, 1) => return Some(known[0].1),
        // Between two finished values; beyond the first or the last.
        (k, n) if k > 0 && k < n => (known[k - 1], known[k]),
        (0, _) => (known[0], known[1]),
        (_, n) => (known[n - 2], known[n - 1]),
    };
    if p1 == p0 {
        return Some(c1);
    }
    Some((c0 + (c1 - c0) * (x - p0) / (p1 - p0)).max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs jobs of `costs` (s) on `threads` list-scheduled threads, each free thread taking
    /// the queue's next job (the queue learning each cost when its job ends) or, with
    /// `listed`, the next in the listed order; returns the wall time.
    fn simulate(costs: &[f64], threads: usize, listed: bool) -> f64 {
        let n = costs.len();
        let param: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let mut q = Queue::new(param, &vec![true; n], &vec![None; n]);
        let mut in_order = 0..n;
        // (time the thread is free, job it is running)
        let mut busy: Vec<(f64, Option<usize>)> = vec![(0.0, None); threads];
        loop {
            // The thread that frees first ends its job, then takes the next.
            let t = (0..threads)
                .min_by(|&a, &b| busy[a].0.total_cmp(&busy[b].0))
                .unwrap();
            let now = busy[t].0;
            if let Some(j) = busy[t].1.take() {
                q.finished(j, costs[j]);
            }
            let next = if listed {
                in_order.next()
            } else {
                q.take_next()
            };
            match next {
                Some(j) => busy[t] = (now + costs[j], Some(j)),
                None => {
                    busy[t].0 = f64::INFINITY;
                    if busy.iter().all(|b| b.1.is_none()) {
                        return now;
                    }
                }
            }
        }
    }

    #[test]
    fn the_estimate_interpolates_between_finished_values_and_extrapolates_beyond_them() {
        let mut q = Queue::new(vec![0.0, 1.0, 2.0, 3.0, 5.0], &[true; 5], &[None; 5]);
        assert_eq!(q.estimate(1), None);
        q.finished(0, 10.0);
        // One finished value: every estimate is its cost.
        assert_eq!(q.estimate(3), Some(10.0));
        q.finished(2, 4.0);
        // Halfway between 10 at 0 and 4 at 2; along that line beyond 2, never below zero.
        assert_eq!(q.estimate(1), Some(7.0));
        assert_eq!(q.estimate(3), Some(1.0));
        assert_eq!(q.estimate(4), Some(0.0));
    }

    #[test]
    fn values_go_in_listed_order_until_costs_are_known_then_costliest_first() {
        let mut q = Queue::new(vec![0.0, 1.0, 2.0, 3.0, 4.0], &[true; 5], &[None; 5]);
        assert_eq!(q.take_next(), Some(0));
        assert_eq!(q.take_next(), Some(1));
        // Costs rise with the parameter: the far end goes next.
        q.finished(0, 1.0);
        q.finished(1, 2.0);
        assert_eq!(q.take_next(), Some(4));
        assert_eq!(q.take_next(), Some(3));
        assert_eq!(q.take_next(), Some(2));
        assert_eq!(q.take_next(), None);
    }

    #[test]
    fn a_sweep_of_very_many_values_goes_in_the_listed_order() {
        let n = LEARNED_UP_TO + 2;
        let mut pending = vec![true; n];
        pending[1] = false;
        let mut q = Queue::new((0..n).map(|i| i as f64).collect(), &pending, &vec![None; n]);
        q.finished(0, 5.0);
        let order: Vec<usize> = std::iter::from_fn(|| q.take_next()).collect();
        let want: Vec<usize> = (0..n).filter(|&i| i != 1).collect();
        assert_eq!(order, want);
    }

    #[test]
    fn values_already_run_are_skipped_and_their_costs_used() {
        let mut q = Queue::new(
            vec![0.0, 1.0, 2.0, 3.0],
            &[false, false, true, true],
            &[Some(5.0), Some(3.0), None, None],
        );
        // Falling costs read from the file: the nearer value, the costlier one, goes first.
        assert_eq!(q.take_next(), Some(2));
        assert_eq!(q.take_next(), Some(3));
        assert_eq!(q.take_next(), None);
    }

    #[test]
    fn four_falling_costs_end_on_the_best_split() {
        // The four clearances of the section-3 tolerance study at rtol 1e-7 (job wall times in
        // s, `section3_tolerance.py`): 0.1, 0.3, 0.5 and 0.7 mm. The best split is
        // 24.3 + 14.9 against 18.8 + 16.2; the sweep used to run 24.3 + 18.8 on one thread.
        let costs = [24.3, 18.8, 16.2, 14.9];
        assert!((simulate(&costs, 2, false) - 39.2).abs() < 1e-9);
    }

    #[test]
    fn costliest_first_beats_the_listed_order_where_the_costliest_values_are_not_all_first() {
        // A cost peaked in the middle of the range, and one highest at both ends.
        let peaked = [5.0, 6.0, 8.0, 12.0, 20.0, 12.0, 8.0, 6.0, 5.0];
        let valley = [20.0, 12.0, 8.0, 6.0, 5.0, 6.0, 8.0, 12.0, 20.0];
        for costs in [&peaked[..], &valley[..]] {
            let (ours, listed) = (simulate(costs, 2, false), simulate(costs, 2, true));
            let ideal = costs.iter().sum::<f64>() / 2.0;
            assert!(ours < listed, "{ours} against {listed}");
            // Graham's LPT bound for 2 threads: 7/6 of the best schedule (itself >= ideal).
            assert!(
                ours <= 7.0 / 6.0 * ideal.max(20.0),
                "{ours} against {ideal}"
            );
        }
    }

    #[test]
    fn a_smooth_falling_cost_profile_ends_within_half_a_value_of_the_ideal() {
        // 40 values whose cost falls like the section-3 sweep's (2.2 times first to last).
        let costs: Vec<f64> = (0..40)
            .map(|i| 10.0 + 12.0 * (-(i as f64) / 10.0).exp())
            .collect();
        let wall = simulate(&costs, 2, false);
        let ideal = costs.iter().sum::<f64>() / 2.0;
        // Costliest first leaves a tail of at most half the last value (about the cheapest,
        // 10.24; the bound allows 10.5).
        assert!(wall <= ideal + 0.5 * 10.5, "{wall} against {ideal}");
    }
}
