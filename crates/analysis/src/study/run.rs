//! Simulation runs with recording.
//!
//! [`simulate`] assembles the initial state, integrates from the scene's start to its end time and,
//! at every sample time (evaluated on the integrator's dense output, so exactly at
//! `t0 + k * interval`), evaluates the model once more to record accelerations, joint reactions,
//! actuator forces and the diagnostics. A non-finite recorded value stops the run with an error
//! naming the time and the quantity: nothing non-finite is ever recorded.
//!
//! What is recorded is declared once ([`Recording::of`]): one [`Channel`](crate::storage::run::Channel) per dataset of the run
//! file, whose columns are observables of [`crate::flow::observe`] (`bodies.B.position.x`, `.y`, `.z`
//! for `/bodies/B/position`), evaluated by the same code a study observes with and written by
//! one generic writer ([`crate::storage::run_file::write_run`]).
//!
//! A run that diverges (the guards of [`jointplay_solver::guard`], a non-finite state, a
//! non-finite recorded value) keeps every sample recorded before the failure:
//! [`RunResult::stopped`] says where and why, and the file written from it is marked incomplete.
//!
//! A run can also be written to its file while it goes ([`simulate_to_file`], [`resume_to_file`],
//! what `jointplay run` does): every [`crate::storage::h5::STREAM_ROWS`] samples are appended to the file
//! and dropped from memory, so a run's memory does not grow with its length. The integration then
//! only reads the states at the sample times (with the contacts' onset history, which the
//! contact laws with hysteresis damping read); the file's writer thread evaluates the recorded
//! quantities from them, beside the integration, to the same values bit for bit (a part the
//! writer is behind with the integrating thread evaluates itself: `Stream`). Of the streamed
//! samples it keeps only those the run figures draw ([`crate::storage::run::drawn`]), thinned so
//! that no excursion is lost: of each bucket of consecutive samples, the first and, per column,
//! the value farthest from it (a force spike is kept at its height, not skipped), the bucket
//! doubling whenever `4 FIGURE_SAMPLES` rows are reached ([`FIGURE_SAMPLES`]). A run of up to
//! `4 FIGURE_SAMPLES` samples draws every sample, as an in-memory run.
//!
//! Every run ends with its hybrid state ([`RunResult::final_state`]: the continuous state with
//! the contact-onset history, the guard's flags and the integrator's memory), written to the run
//! file ([`crate::storage::hybrid`]). [`resume`] continues a run from such a state to the scene's end
//! time, without assembling it again: a run of 2T and a run of T continued for T from its file
//! are the same run, bit for bit when T lies on a fixed-step method's grid.

use jointplay_solver::dynamics::{AssemblyReport, Mechanism, Workspace};
use jointplay_solver::model::{Model, State};
use jointplay_solver::ode::{Flow, OdeSystem, Stats, advance};
use jointplay_solver::state::HybridState;

use std::path::{Path, PathBuf};
use std::sync::mpsc;

use crate::Result;
use crate::progress::Stop;
use crate::storage::h5::STREAM_ROWS;
use crate::storage::run::{INTERRUPTED, Recording, RunResult, Stopped};
use crate::storage::run_file::{Meta, OpenedRun, RunWriter};

/// Simulates `model` from `state` (assembled first) and records its outputs.
/// `progress` receives the fraction of the span done after every sample. Errors only when the
/// initial state cannot be assembled; a failure later returns what was recorded, with
/// [`RunResult::stopped`] set.
pub fn simulate(model: &Model, state: State, progress: &mut dyn FnMut(f64)) -> Result<RunResult> {
    simulate_until(model, state, progress, &Stop::new())
}

/// [`simulate`] that also ends when `stop` is requested (checked at every sample): the run then
/// keeps the samples recorded so far, and [`RunResult::stopped`] says it was interrupted and
/// when ([`RunResult::interrupted`]).
pub fn simulate_until(
    model: &Model,
    mut state: State,
    progress: &mut dyn FnMut(f64),
    stop: &Stop,
) -> Result<RunResult> {
    let assembly = model.assemble(&mut state)?;
    record(
        model,
        (HybridState::new(state.t, state.y), false),
        assembly,
        progress,
        stop,
        None,
    )
}

/// Rows a run written to its file keeps in memory for its figures: between twice and four times
/// this once it is long (see the module documentation).
pub const FIGURE_SAMPLES: usize = 10_000;

/// What a run written to its file ([`simulate_to_file`]) leaves besides its [`RunResult`].
#[derive(Debug, Clone)]
pub struct Written {
    /// The run file.
    pub path: PathBuf,
    /// Samples written.
    pub samples: usize,
    /// The largest constraint drift and velocity drift over all samples, when the scene
    /// records its diagnostics.
    pub max_drift: Option<(f64, f64)>,
    /// The [`RunResult::recording`] returned with it holds, of every bucket of this many
    /// samples, the first and the farthest excursion (see the module documentation); 1: every
    /// sample.
    pub bucket: usize,
}

/// The states of a block of samples, read on the integrator's dense output: what the writer
/// thread evaluates the recorded quantities from.
#[derive(Debug, Default)]
struct States {
    time: Vec<f64>,
    /// The continuous state at each sample, one after the other.
    y: Vec<f64>,
    /// The contact-onset history at each sample (the approach velocities the contact laws with
    /// hysteresis damping read), one after the other; empty for a model without contacts.
    onset: Vec<f64>,
}

impl States {
    fn clear(&mut self) {
        self.time.clear();
        self.y.clear();
        self.onset.clear();
    }
}

/// What a streamed run keeps besides its file: the channels the figures draw, thinned so that
/// no excursion is lost, and the largest constraint and velocity drift.
///
/// The samples are taken in buckets of `bucket` consecutive samples. A bucket of one sample is
/// kept as it is; a larger bucket as two rows: its first sample, and per column the value
/// farthest from the first row's within the bucket (a force spike, a turning point), placed at
/// the bucket's last sample time. A journal's eccentricity vector is kept whole (the sample
/// farthest from the first row's, so an orbit shows only positions the journal took). Whenever
/// the rows reach `4 FIGURE_SAMPLES`, adjacent buckets merge by the same rule and `bucket`
/// doubles: a figure a thousand pixels wide gets at least ten buckets per pixel column, and the
/// largest excursion of each of them.
struct Kept {
    thin: Recording,
    /// Per channel: kept for the figures.
    keep: Vec<bool>,
    /// Per channel: kept as a vector (one distance over its columns), not column by column.
    vector: Vec<bool>,
    /// Samples per bucket.
    bucket: usize,
    /// Samples in the last bucket so far (0: the next sample opens a bucket).
    open: usize,
    /// The channels of the constraint and velocity drift, and their largest values so far.
    drift: Option<([usize; 2], [f64; 2])>,
    /// Samples seen.
    rows: usize,
}

/// Of the candidate rows `cands` (each a slice of one channel's columns), the index of the one
/// farthest from `first`: per column when `vector` is false (then one index per column), else
/// one index for the whole row by its Euclidean distance.
fn farthest(first: &[f64], cands: &[&[f64]], vector: bool) -> Vec<usize> {
    let far = |d: &dyn Fn(&[f64]) -> f64| {
        let mut best = (0, f64::NEG_INFINITY);
        for (i, c) in cands.iter().enumerate() {
            let v = d(c);
            if v > best.1 {
                best = (i, v);
            }
        }
        best.0
    };
    if vector {
        let i = far(&|c| {
            c.iter()
                .zip(first)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
        });
        vec![i; first.len()]
    } else {
        (0..first.len())
            .map(|k| far(&|c| (c[k] - first[k]).abs()))
            .collect()
    }
}

impl Kept {
    fn new(rec: &Recording) -> Kept {
        let mut thin = rec.clone();
        thin.time.clear();
        for c in &mut thin.channels {
            c.values = Vec::new();
        }
        let keep = rec
            .channels
            .iter()
            .map(|c| crate::storage::run::drawn(&c.dataset))
            .collect();
        let vector = rec
            .channels
            .iter()
            .map(|c| c.dataset.ends_with("/radial_eccentricity"))
            .collect();
        let at = |d: &str| rec.channels.iter().position(|c| c.dataset == d);
        let drift = at("diagnostics/constraint_drift")
            .zip(at("diagnostics/velocity_drift"))
            .map(|(p, v)| ([p, v], [0.0; 2]));
        Kept {
            thin,
            keep,
            vector,
            bucket: 1,
            open: 0,
            drift,
            rows: 0,
        }
    }

    /// Takes in the next samples of the run.
    fn add(&mut self, rec: &Recording) {
        self.rows += rec.time.len();
        if let Some((idx, max)) = &mut self.drift {
            for (m, &i) in max.iter_mut().zip(idx.iter()) {
                *m = rec.channels[i]
                    .values
                    .iter()
                    .fold(*m, |a, v| a.max(v.abs()));
            }
        }
        for (i, &t) in rec.time.iter().enumerate() {
            self.add_sample(rec, i, t);
            if self.open == 0 && self.thin.time.len() >= 4 * FIGURE_SAMPLES {
                self.merge();
            }
        }
    }

    /// Sample `i` (at time `t`) of `rec` into the open bucket, or a new one.
    fn add_sample(&mut self, rec: &Recording, i: usize, t: f64) {
        let opening = self.open == 0;
        if opening {
            self.thin.time.push(t);
            if self.bucket > 1 {
                self.thin.time.push(t);
            }
        } else if let Some(last) = self.thin.time.last_mut() {
            *last = t;
        }
        for (((c, th), &keep), &vector) in rec
            .channels
            .iter()
            .zip(&mut self.thin.channels)
            .zip(&self.keep)
            .zip(&self.vector)
        {
            if !keep {
                continue;
            }
            let w = c.width();
            let sample = &c.values[i * w..(i + 1) * w];
            if opening {
                th.values.extend_from_slice(sample);
                if self.bucket > 1 {
                    th.values.extend_from_slice(sample);
                }
                continue;
            }
            let n = th.values.len();
            let (first, second) = th.values[n - 2 * w..].split_at_mut(w);
            // The rule of `farthest` for two candidates, without its allocation: this runs for
            // every sample of every drawn channel on the writer thread.
            let d = |a: f64, b: f64| (a - b) * (a - b);
            if vector {
                let dist = |r: &[f64]| r.iter().zip(&*first).map(|(a, b)| d(*a, *b)).sum::<f64>();
                if dist(sample) > dist(second) {
                    second.copy_from_slice(sample);
                }
            } else {
                for ((s2, &x), &f) in second.iter_mut().zip(sample).zip(&*first) {
                    if d(x, f) > d(*s2, f) {
                        *s2 = x;
                    }
                }
            }
        }
        self.open = (self.open + 1) % self.bucket;
    }

    /// Merges adjacent buckets (see [`Kept`]): the number of rows halves, `bucket` doubles.
    fn merge(&mut self) {
        if self.bucket == 1 {
            // Pairs of single samples are buckets of two already: the first sample, and the
            // second (the only one there is to be farthest).
            if self.thin.time.len().is_multiple_of(2) {
                self.bucket = 2;
            }
            return;
        }
        let rows = self.thin.time.len();
        if !rows.is_multiple_of(4) {
            return;
        }
        let time: Vec<f64> = self
            .thin
            .time
            .chunks_exact(4)
            .flat_map(|q| [q[0], q[3]])
            .collect();
        self.thin.time = time;
        for (c, &vector) in self.thin.channels.iter_mut().zip(&self.vector) {
            if c.values.is_empty() {
                continue;
            }
            let w = c.width();
            let mut out = Vec::with_capacity(c.values.len() / 2);
            for q in c.values.chunks_exact(4 * w) {
                let (first, rest) = q.split_at(w);
                let cands: Vec<&[f64]> = rest.chunks_exact(w).collect();
                let pick = farthest(first, &cands, vector);
                out.extend_from_slice(first);
                out.extend(pick.iter().enumerate().map(|(k, &p)| cands[p][k]));
            }
            c.values = out;
        }
        self.bucket *= 2;
    }
}

/// The writer thread's side: evaluates the recorded quantities at the states it is handed, in a
/// model and workspace of its own.
struct Sampler {
    model: Model,
    ws: Workspace,
    order: Vec<usize>,
    /// The samples evaluated and not yet written (up to a block); its memory is reused from
    /// block to block.
    block: Recording,
    /// The recording's declaration, without samples (the helper's: a part of recorded values
    /// when the writer has none to give back).
    empty: Recording,
}

impl Sampler {
    /// Evaluates the samples of `s` and appends them to [`Sampler::block`]: by the threads of
    /// rayon's pool, each with a workspace of its own, when `parallel` (the run's last samples,
    /// which nothing else runs beside), in turn otherwise. The samples are independent of one
    /// another (each carries its onset history), so the values are the same either way, bit for
    /// bit. A sample that fails ends the block before it and gives where and why the run stops.
    fn evaluate(&mut self, s: &States, parallel: bool) -> Option<Stopped> {
        use rayon::prelude::*;
        let n = s.time.len();
        let parts = if parallel {
            rayon::current_num_threads().min(n)
        } else {
            1
        };
        if parts <= 1 {
            return sample_states(
                &mut self.block,
                &self.order,
                &self.model,
                &mut self.ws,
                s,
                0..n,
            );
        }
        let len = n.div_ceil(parts);
        let (model, order, empty) = (&self.model, &self.order, &self.empty);
        // The first part goes into the block itself (whose memory holds a whole block), the
        // others into recordings of their own, appended in order.
        let mut parts: Vec<Recording> = (0..parts)
            .map(|p| match p {
                0 => std::mem::take(&mut self.block),
                _ => empty.clone(),
            })
            .collect();
        let stops: Vec<Option<Stopped>> = parts
            .par_iter_mut()
            .enumerate()
            .map(|(p, rec)| {
                let mut ws = Workspace::new(model);
                let end = ((p + 1) * len).min(n);
                sample_states(rec, order, model, &mut ws, s, p * len..end)
            })
            .collect();
        let mut parts = parts.into_iter().zip(stops);
        // There are at least two parts; those after a stop are dropped.
        let (block, mut stopped) = parts.next()?;
        self.block = block;
        for (rec, s) in parts {
            if stopped.is_some() {
                break;
            }
            self.block.extend(&rec);
            stopped = s;
        }
        stopped
    }
}

/// Evaluates the samples `range` of `s` into `rec`, in turn, in `ws`; the first that fails is
/// dropped whole and ends the evaluation, with where and why.
fn sample_states(
    rec: &mut Recording,
    order: &[usize],
    model: &Model,
    ws: &mut Workspace,
    s: &States,
    range: std::ops::Range<usize>,
) -> Option<Stopped> {
    let dim = s.y.len() / s.time.len().max(1);
    let contacts = s.onset.len() / s.time.len().max(1);
    for i in range {
        ws.onset
            .copy_from_slice(&s.onset[i * contacts..(i + 1) * contacts]);
        let t = s.time[i];
        if let Err(e) = rec.sample_at(order, model, ws, t, &s.y[i * dim..(i + 1) * dim]) {
            return Some(Stopped::of(&e, t));
        }
    }
    None
}

/// How the writer thread ended: the writer, what the run keeps besides its file, and either the
/// first error writing it or where the recorded values stopped the run ([`Sampler::evaluate`]);
/// an error creating the file's datasets (the partial file then removed) otherwise.
type Ended = Result<(RunWriter, Kept, Result<Option<Stopped>>)>;

/// Samples handed to the writer thread ([`PART_ROWS`] of them, or the run's last ones): the
/// states at their sample times, which the writer evaluates, or the recorded values the
/// integrating thread evaluated itself while the writer was behind, with where a sample stopped
/// the run if one did.
enum Part {
    States(States),
    Recorded(Recording, Option<Stopped>),
}

/// Samples in a part handed to a streamed run's writer thread: a fraction of a block
/// ([`STREAM_ROWS`]), so that little is left to evaluate when the integration ends.
const PART_ROWS: usize = STREAM_ROWS / 8;

/// Parts that may wait for the writer thread (a block's worth) before the integration evaluates
/// the next itself.
const WAITING: usize = STREAM_ROWS / PART_ROWS;

/// Where a streamed run's samples go: the states at the sample times to a thread of their own,
/// which evaluates the recorded quantities from them, writes them to the file and keeps the
/// channels the figures draw, thinned without losing an excursion ([`Kept`]).
///
/// The integration only reads the states on its dense output (and the contacts' onset history)
/// and hands each part of [`PART_ROWS`] of them over a channel that holds at most [`WAITING`]
/// waiting parts (a block of [`STREAM_ROWS`], one chunk of the file); the writer thread
/// evaluates the recording at them (the accelerations and multipliers that forces and
/// reactions need, then every observable: before, a sixth of the run's time on the integrating
/// thread of the mixed 4-UPS/RPU with its 1 ms output) as they come, and once a block's worth
/// is evaluated it shuffles, deflates ([`crate::storage::chunk`]) and appends them, beside the
/// integration on the other core. The last part, which the integration no longer runs beside,
/// is evaluated, and the last block compressed, by every thread of rayon's pool: handed over in
/// parts, the samples left to evaluate after the integration are, when the writer keeps up,
/// fewer than a part, not up to a block (on a 10 s run of the mixed 4-UPS/RPU with 1 ms output,
/// 17 of its 10 001 samples instead of 1 809: the time from the integration's end to the file's
/// close fell from 78 to 48 ms; a writer that is behind has up to a block's worth of parts
/// waiting, which it evaluates in turn, as before). When the
/// writer falls behind (a block's worth of parts already waits in the channel when the next is
/// full, as with an integrator that needs few right-hand sides per sample), the integration
/// evaluates that part itself instead of waiting, and hands over its recorded values, which the
/// writer then only gathers, compresses and appends: the work then splits between the two
/// cores by itself. Every sample is evaluated alike wherever it is (its state and onset
/// history, in a workspace of the thread's own), so the file is the same bit for bit. The
/// writer hands each part of states or values back, emptied, and the integration fills it
/// again, so that no part's memory is allocated (and its pages faulted in) anew. A sample
/// whose recorded value is not finite stops the run there: the samples before it are written
/// and the writer thread ends; the integration stops at once when it evaluated the part
/// itself, and otherwise when it next hands a part over, at most [`WAITING`] + 1 parts after
/// the one that failed (those may wait in the channel).
struct Stream {
    /// The parts for the writer thread; `None` once closed.
    tx: Option<mpsc::SyncSender<(Part, bool)>>,
    thread: Option<std::thread::JoinHandle<Ended>>,
    /// Parts of states the writer has evaluated, handed back emptied to be filled again.
    spare: mpsc::Receiver<States>,
    /// Parts of recorded values the writer has gathered, handed back to be filled again.
    spare_recorded: mpsc::Receiver<Recording>,
    /// The part filling.
    states: States,
    /// The integrating thread's own evaluation of the parts the writer was behind with.
    helper: Sampler,
    /// Tests: which parts the integrating thread evaluates, and how many it did.
    #[cfg(test)]
    probe: Probe,
    /// The partial file, for the error of a writer thread that panicked.
    partial: PathBuf,
    /// Set when the writer thread was found gone, or a sample stopped the run, before its end.
    gone: bool,
}

/// Tests: `helps(i)` says whether the integrating thread evaluates part `i` (0, 1, ...; never
/// the last), as when the writer is behind with it, the other parts waiting for the writer
/// (`None`: as a run); the parts handed over, and those the integrating thread evaluated.
#[cfg(test)]
#[derive(Default)]
struct Probe {
    helps: Option<fn(usize) -> bool>,
    parts: usize,
    helped: usize,
}

impl Stream {
    /// `rec`: the run's recording, without samples yet ([`Recording::of`]); `file`: the run's
    /// file, whose datasets the writer thread creates first ([`OpenedRun::declare`]).
    fn new(model: &Model, file: OpenedRun, rec: &Recording) -> Stream {
        let sampler = || Sampler {
            model: model.clone(),
            ws: Workspace::new(model),
            order: rec.order(),
            block: rec.clone(),
            empty: rec.clone(),
        };
        let mut own = sampler();
        let mut kept = Kept::new(rec);
        let partial = file.partial().to_path_buf();
        let (tx, rx) = mpsc::sync_channel::<(Part, bool)>(WAITING);
        // Room for every part there can be, so that handing one back never waits.
        let (back, spare) = mpsc::sync_channel::<States>(WAITING + 2);
        let (back_recorded, spare_recorded) = mpsc::sync_channel::<Recording>(WAITING + 2);
        let thread = std::thread::spawn(move || {
            let mut writer = file.declare(&own.empty)?;
            // The evaluated samples gather in `own.block` until they fill a chunk.
            let write = |writer: &mut RunWriter, own: &mut Sampler, kept: &mut Kept, last| {
                kept.add(&own.block);
                let written = writer.append(&own.block, last);
                own.block.truncate(0);
                written
            };
            for (part, last) in rx {
                let stopped = match &part {
                    Part::States(states) => own.evaluate(states, last),
                    Part::Recorded(recorded, stopped) => {
                        own.block.extend(recorded);
                        stopped.clone()
                    }
                };
                let full = own.block.time.len() >= STREAM_ROWS || last || stopped.is_some();
                if full && let Err(e) = write(&mut writer, &mut own, &mut kept, last) {
                    return Ok((writer, kept, Err(e)));
                }
                if stopped.is_some() {
                    return Ok((writer, kept, Ok(stopped)));
                }
                // Nobody to take them back once the run is over.
                match part {
                    Part::States(mut states) => {
                        states.clear();
                        let _ = back.try_send(states);
                    }
                    Part::Recorded(recorded, _) => {
                        let _ = back_recorded.try_send(recorded);
                    }
                }
            }
            // The integration ended without its last part (its writer gone, or an error):
            // what was evaluated is written.
            if let Err(e) = write(&mut writer, &mut own, &mut kept, false) {
                return Ok((writer, kept, Err(e)));
            }
            Ok((writer, kept, Ok(None)))
        });
        Stream {
            tx: Some(tx),
            thread: Some(thread),
            spare,
            spare_recorded,
            states: States::default(),
            helper: sampler(),
            #[cfg(test)]
            probe: Probe::default(),
            partial,
            gone: false,
        }
    }

    /// Adds the sample at `t`, state `y`, with the contacts' onset history `onset`, and hands
    /// the part over when it is full. False when the writer thread is gone (at an error, or
    /// where the recorded values stopped the run: [`Stream::close`] says which).
    fn push(&mut self, t: f64, y: &[f64], onset: &[f64]) -> bool {
        self.states.time.push(t);
        self.states.y.extend_from_slice(y);
        self.states.onset.extend_from_slice(onset);
        self.states.time.len() < PART_ROWS || self.send(false)
    }

    /// Hands the part over (`last`: the run's last samples); false when the writer thread is
    /// gone or a sample of the part stopped the run. A part that is not the last, and finds the
    /// writer behind ([`WAITING`] parts waiting), is evaluated here first.
    fn send(&mut self, last: bool) -> bool {
        use mpsc::TrySendError;
        if self.gone {
            return false;
        }
        let Some(tx) = self.tx.clone() else {
            self.gone = true;
            return false;
        };
        let part = Part::States(std::mem::take(&mut self.states));
        // The states to fill next: a part the writer gave back, once this one is handed over.
        let refill = |stream: &mut Stream| {
            stream.states = stream.spare.try_recv().unwrap_or_default();
        };
        #[cfg(test)]
        {
            self.probe.parts += 1;
        }
        let sent = if last {
            let sent = tx.send((part, last)).is_ok();
            refill(self);
            sent
        } else {
            #[cfg(test)]
            let tried = match self.probe.helps {
                Some(helps) if helps(self.probe.parts - 1) => Err(TrySendError::Full((part, last))),
                Some(_) => tx
                    .send((part, last))
                    .map_err(|e| TrySendError::Disconnected(e.0)),
                None => tx.try_send((part, last)),
            };
            #[cfg(not(test))]
            let tried = tx.try_send((part, last));
            match tried {
                Ok(()) => {
                    refill(self);
                    true
                }
                Err(TrySendError::Disconnected(_)) => false,
                Err(TrySendError::Full((Part::States(mut states), _))) => {
                    self.helper.block.truncate(0);
                    let stopped = self.helper.evaluate(&states, false);
                    #[cfg(test)]
                    {
                        self.probe.helped += 1;
                    }
                    // The part's states are done with: they are filled again, and the
                    // helper's values go over, replaced by a part the writer gave back.
                    states.clear();
                    self.states = states;
                    let recorded = std::mem::replace(
                        &mut self.helper.block,
                        self.spare_recorded
                            .try_recv()
                            .unwrap_or_else(|_| self.helper.empty.clone()),
                    );
                    let stops = stopped.is_some();
                    tx.send((Part::Recorded(recorded, stopped), last)).is_ok() && !stops
                }
                Err(TrySendError::Full(_)) => unreachable!("a part of states was sent"),
            }
        };
        self.gone = !sent;
        sent
    }

    /// Waits for the writer thread to write every part handed to it and returns the writer,
    /// what the run keeps and where the recorded values stopped the run, if they did; on the
    /// thread's error the partial file is removed and the error returned. `None` when already
    /// closed.
    fn close(&mut self) -> Option<Result<(RunWriter, Kept, Option<Stopped>)>> {
        self.tx = None;
        let thread = self.thread.take()?;
        Some(match thread.join() {
            Ok(Ok((writer, kept, Ok(stopped)))) => Ok((writer, kept, stopped)),
            Ok(Ok((writer, _, Err(e)))) => {
                writer.discard();
                Err(e)
            }
            Ok(Err(e)) => Err(e),
            Err(_) => {
                // The thread's writer was dropped as it unwound, closing the file.
                let _ = std::fs::remove_file(&self.partial);
                Err(crate::Error::Io {
                    file: self.partial.clone(),
                    message: "the thread writing the file stopped unexpectedly".into(),
                })
            }
        })
    }

    /// The error of a writer that is gone before the run's end without an error of its own.
    fn ended_early(&self) -> crate::Error {
        crate::Error::Io {
            file: self.partial.clone(),
            message: "the file's writer stopped before the run's end".into(),
        }
    }
}

/// [`simulate`] that writes the run to `dir/<scene name>.h5` while it goes (layout and values
/// those of [`crate::storage::run_file::write_run`]; see the module documentation), keeping only what its
/// figures draw: the returned [`RunResult::recording`] holds the channels
/// [`crate::storage::run::drawn`] names, thinned to the first sample and the farthest excursion
/// of every [`Written::bucket`] samples, and no values of the others. A run
/// that stops early still finishes its file, marked incomplete (`complete = 0`) with the
/// samples before the failure.
pub fn simulate_to_file(
    model: &Model,
    mut state: State,
    progress: &mut dyn FnMut(f64),
    dir: &Path,
    meta: &Meta,
) -> Result<(RunResult, Written)> {
    let assembly = model.assemble(&mut state)?;
    stream(
        model,
        (HybridState::new(state.t, state.y), false),
        assembly,
        progress,
        dir,
        meta,
    )
}

/// [`resume`] written to its file while it goes, as [`simulate_to_file`].
pub fn resume_to_file(
    model: &Model,
    state: HybridState,
    progress: &mut dyn FnMut(f64),
    dir: &Path,
    meta: &Meta,
) -> Result<(RunResult, Written)> {
    let assembly = resumable(model, &state)?;
    stream(model, (state, true), assembly, progress, dir, meta)
}

/// `(state, resumed)`: the state the run starts from, and whether it is a file's final state
/// (whose sample is in that file) rather than a fresh start.
fn stream(
    model: &Model,
    state: (HybridState, bool),
    assembly: AssemblyReport,
    progress: &mut dyn FnMut(f64),
    dir: &Path,
    meta: &Meta,
) -> Result<(RunResult, Written)> {
    let rec = Recording::of(model)?;
    let file = RunWriter::open(dir, meta)?;
    let mut sink = Stream::new(model, file, &rec);
    let res = record(
        model,
        state,
        assembly,
        progress,
        &Stop::new(),
        Some(&mut sink),
    );
    let closed = sink.close();
    let (run, writer, kept, stopped) = match (res, closed) {
        (Ok(run), Some(Ok((writer, kept, stopped)))) => (run, writer, kept, stopped),
        (Err(e), closed) => {
            if let Some(Ok((writer, ..))) = closed {
                writer.discard();
            }
            return Err(e);
        }
        (Ok(_), Some(Err(e))) => return Err(e),
        (Ok(_), None) => return Err(sink.ended_early()),
    };
    // Where the recorded values stopped the run comes first: the integration went on past it
    // until it learnt of it.
    let stopped = match (stopped, sink.gone) {
        (Some(s), _) => Some(s),
        (None, false) => run.stopped,
        (None, true) => {
            writer.discard();
            return Err(sink.ended_early());
        }
    };
    let samples = writer.rows();
    let Kept {
        thin,
        bucket,
        drift,
        ..
    } = kept;
    let run = RunResult {
        recording: thin,
        stopped,
        ..run
    };
    let path = writer.finish(meta, &run)?;
    Ok((
        run,
        Written {
            path,
            samples,
            max_drift: drift.map(|(_, m)| (m[0], m[1])),
            bucket,
        },
    ))
}

/// Continues a run from `state` (the final state of an earlier run of the same model, as
/// [`crate::storage::hybrid::read_state`] reads it from its file) to the scene's end time, with its
/// contact-onset history, guard flags and integrator memory, and records the samples of the
/// scene's output grid from the state's time on. The state is not assembled again (that would
/// move it); the assembly report gives its constraint residuals instead. An error when the
/// state does not fit the model or lies at or after the end time.
pub fn resume(
    model: &Model,
    state: HybridState,
    progress: &mut dyn FnMut(f64),
) -> Result<RunResult> {
    let assembly = resumable(model, &state)?;
    record(model, (state, true), assembly, progress, &Stop::new(), None)
}

/// Runs `model` again from `state` (a state a file keeps: a sweep value's end, a periodic
/// orbit's strobe point) to its end time with the state's contact-onset history, recording from
/// the state itself on (its first sample at `state.t`), as a motion shown again rather than a
/// run continued. The state is not assembled again.
pub fn rerun(model: &Model, state: HybridState) -> Result<RunResult> {
    let assembly = resumable(model, &state)?;
    record(
        model,
        (state, false),
        assembly,
        &mut |_| {},
        &Stop::new(),
        None,
    )
}

/// Checks that a run can continue from `state` and reports its constraint residuals.
fn resumable(model: &Model, state: &HybridState) -> Result<AssemblyReport> {
    let mut sys = Mechanism::new(model);
    sys.load_memory(state)?;
    let (t0, t1) = (model.settings.start_time, model.settings.end_time);
    // A state before the start time is not one of this scene's runs, and continuing from far
    // before it (t = -1e300) would pass the scene's bound on the steps of a run and never end.
    if !state.t.is_finite()
        || state.t < t0
        || state.t >= t1
        || !state.y.iter().all(|v| v.is_finite())
    {
        return Err(jointplay_solver::Error::Invalid {
            file: model.file.clone(),
            field: "state".into(),
            message: format!(
                "cannot continue from the state at t = {} s: it must be finite, not before the \
                 scene's start time {t0} s and before its end time {t1} s",
                state.t
            ),
        }
        .into());
    }
    model.drift(state.t, &state.y, &mut sys.ws);
    let max = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let (p, v) = (max(&sys.ws.phi), max(&sys.ws.phi_dot));
    Ok(AssemblyReport {
        iterations: 0,
        initial_residual: p,
        final_residual: p,
        initial_velocity_residual: v,
        final_velocity_residual: v,
    })
}

/// Integrates `model` from the hybrid state `state` to the end time and records the outputs at
/// the sample times from `state.t` on (after it when `resumed`: the file continued holds it);
/// with a `sink`, the states at the sample times go to it instead, to be evaluated and written
/// by its thread (whose end, early or not, the caller learns from [`Stream::close`]).
fn record(
    model: &Model,
    (mut state, resumed): (HybridState, bool),
    assembly: AssemblyReport,
    progress: &mut dyn FnMut(f64),
    stop: &Stop,
    mut sink: Option<&mut Stream>,
) -> Result<RunResult> {
    let mut samples = model.sample_times();
    // A run continued from a file starts after the samples that file holds: those up to and at
    // its final state.
    samples.retain(|&t| if resumed { t > state.t } else { t >= state.t });
    // A sink's thread has the recording's declaration; the run returns what the sink keeps.
    let mut rec = match sink {
        Some(_) => Recording::default(),
        None => Recording::of(model)?,
    };
    let order = rec.order();
    let (t0, t1) = (state.t, model.settings.end_time);
    let mut failure = None;
    let mut requested = None;
    // Outputs are evaluated with the system's own workspace, so that they see its contact
    // history; a sink is handed the history with each state.
    let mut observe = |sys: &mut Mechanism, t: f64, y: &[f64]| -> Result<()> {
        match sink.as_deref_mut() {
            Some(s) => {
                // The writer thread is gone: the caller learns why when it closes the stream.
                if !s.push(t, y, &sys.ws.onset) {
                    return Err(crate::Error::Interrupted { time: Some(t) });
                }
            }
            None => rec.sample_at(&order, model, &mut sys.ws, t, y)?,
        }
        progress((t - t0) / (t1 - t0));
        Ok(())
    };
    let mut sys = Mechanism::new(model);
    // A fresh start with a journal inside its housing's wall meets that contact's force at once.
    if !resumed {
        for p in model.penetrations(&state.y, &mut sys.ws) {
            sys.warnings.push(jointplay_solver::guard::Warning {
                time: t0,
                message: format!("at the start, t = {t0} s: {p}"),
            });
        }
    }
    let checked = sys
        .load_memory(&state)
        .and_then(|()| sys.check_initial(t0, &state.y));
    let (stats, res) = match checked {
        Err(e) => (Stats::default(), Err(e)),
        Ok(()) => advance(
            &mut sys,
            model.settings.method,
            &mut state,
            t1,
            &samples,
            |sys, t, y| match observe(sys, t, y) {
                // A stop on request ends the run with the step that holds the sample, its later
                // samples recorded too: the file then holds every sample up to its final state,
                // and `--from` it goes on as the run not stopped would.
                Ok(()) if stop.requested() => {
                    requested.get_or_insert(t);
                    Flow::StopAfterStep
                }
                Ok(()) => Flow::Continue,
                Err(e) => {
                    failure = Some((e, t));
                    Flow::Stop
                }
            },
            None,
        ),
    };
    let stopped = match (failure, res) {
        // The writer thread is gone: nothing of the sample at `time` was recorded.
        (Some((crate::Error::Interrupted { time: Some(time) }, _)), _) => Some(Stopped {
            time,
            message: INTERRUPTED.into(),
        }),
        // The failed sample was dropped whole.
        (Some((e, t_fail)), _) => Some(Stopped::of(&e, t_fail)),
        (None, Err(e)) => Some(Stopped::from_error(&e, t0)),
        // Stopped on request before the end time, every sample up to the final state kept.
        (None, Ok(())) => requested.filter(|_| state.t < t1).map(|time| Stopped {
            time,
            message: INTERRUPTED.into(),
        }),
    };
    if let Some(s) = sink {
        // A writer thread found gone here is reported by `Stream::close`.
        s.send(true);
    }
    Ok(RunResult {
        recording: rec,
        stats,
        assembly,
        final_state: state,
        warnings: sys.warnings,
        stopped,
    })
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use crate::flow::observe::Observable;

    use jointplay_solver::scene::SceneSpec;

    use super::*;
    use crate::storage::run_file::Meta;

    fn model(scene: &str) -> (Model, State) {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../data/scenes")
            .join(scene);
        Model::compile(&SceneSpec::load(&path).unwrap()).unwrap()
    }

    /// `output.significant_bits` by quantity accepts exactly the quantities a run file holds:
    /// every rounded dataset of the bundled clearance mechanisms (spherical, spatial revolute
    /// with faces, planar revolute, drives, diagnostics) ends in a name of
    /// [`jointplay_solver::model::ROUNDED_QUANTITIES`], and every name of it occurs.
    #[test]
    fn the_quantities_significant_bits_names_are_those_of_the_run_files() {
        use jointplay_solver::model::ROUNDED_QUANTITIES;
        let mut seen = std::collections::BTreeSet::new();
        for scene in ["4ups-rpu-mixed.toml", "slider-crank-clearance.toml"] {
            let rec = Recording::of(&model(scene).0).unwrap();
            for c in &rec.channels {
                let q = c.dataset.rsplit('/').next().unwrap();
                assert_eq!(ROUNDED_QUANTITIES.contains(&q), !c.flag, "{}", c.dataset);
                seen.insert(q.to_string());
            }
        }
        let missing: Vec<_> = ROUNDED_QUANTITIES
            .iter()
            .filter(|q| !seen.contains(**q))
            .collect();
        assert!(missing.is_empty(), "{missing:?}");
    }

    #[test]
    fn every_dataset_of_a_4ups_rpu_run_is_made_of_registry_paths() {
        let (m, _) = model("4ups-rpu-mixed.toml");
        let rec = Recording::of(&m).unwrap();
        assert!(!rec.clearances.is_empty() && rec.members("drives").count() == 5);
        for c in &rec.channels {
            assert!(!c.columns.is_empty(), "{}", c.dataset);
            for o in &c.columns {
                // The column is the observable of its path, in the dataset's unit ...
                assert_eq!(Observable::for_run(&m, &o.path).as_ref(), Ok(o));
                assert_eq!(o.unit, c.unit, "{}", o.path);
                // ... which a study can observe too, but for the diagnostics.
                assert_eq!(
                    Observable::for_model(&m, &o.path).is_ok(),
                    !o.is_diagnostic(),
                    "{}",
                    o.path
                );
                // The dataset is the path without its component (none for a scalar).
                let stem = if c.scalar {
                    o.path.as_str()
                } else {
                    o.path.rsplit_once('.').unwrap().0
                };
                assert_eq!(stem.replace('.', "/"), c.dataset);
            }
        }
        let names = |prefix: &str| -> Vec<&str> {
            rec.channels
                .iter()
                .filter_map(|c| c.dataset.strip_prefix(prefix))
                .collect()
        };
        assert_eq!(
            names("bodies/platform/"),
            [
                "position",
                "orientation",
                "velocity",
                "angular_velocity",
                "acceleration",
                "angular_acceleration"
            ]
        );
        // A spatial revolute with clearance, with its contacts as columns.
        let r1 = rec.clearances.iter().find(|c| c.name == "R1").unwrap();
        assert_eq!(r1.contacts, ["P", "Q", "M", "N"]);
        assert_eq!(
            names("joints/R1/"),
            [
                "eccentricity",
                "eccentricity_global",
                "radial_eccentricity",
                "radial_eccentricity_rate",
                "end_eccentricity",
                "penetration",
                "penetration_rate",
                "normal_force",
                "friction_force",
                "contact_state",
                "force_on_journal",
                "moment_on_journal",
                "force_on_housing",
                "moment_on_housing"
            ]
        );
        let state = rec.channel("joints/R1/contact_state").unwrap();
        assert!(
            state.flag
                && state.width() == 4
                && state.columns[3].path == "joints.R1.contact_state.N"
        );
        assert_eq!(
            names("diagnostics/"),
            ["constraint_drift", "velocity_drift", "energy"]
        );
        // The groups come parents first.
        for (i, g) in rec.groups.iter().enumerate() {
            if let Some((parent, _)) = g.path.rsplit_once('/') {
                assert!(
                    rec.groups[..i].iter().any(|p| p.path == parent),
                    "{}",
                    g.path
                );
            }
        }
    }

    #[test]
    fn a_recorded_value_is_the_study_observable_of_its_path_at_that_time() {
        let (mut m, state) = model("4ups-rpu-mixed.toml");
        m.settings.end_time = m.settings.start_time + 0.02;
        let run = simulate(&m, state, &mut |_| {}).unwrap();
        let rec = &run.recording;
        // The last sample is the end time, where the run's final state lies: evaluate the study
        // observables there as a study does (a full evaluation, then Observable::eval_model).
        let last = rec.time.len() - 1;
        let end = &run.final_state;
        assert_eq!(rec.time[last], end.t);
        let mut sys = Mechanism::new(&m);
        sys.load_memory(end).unwrap();
        m.accelerations(end.t, &end.y, &mut sys.ws);
        let mut compared = 0;
        for c in rec.channels.iter().filter(|c| c.stage < 4) {
            let row = c.rows().nth(last).unwrap();
            for (o, &v) in c.columns.iter().zip(row) {
                let study = Observable::for_model(&m, &o.path).unwrap();
                let w = study.eval_model(&m, &sys.ws, end.t, &end.y);
                assert_eq!(
                    v.to_bits(),
                    w.to_bits(),
                    "{}: recorded {v}, study {w}",
                    o.path
                );
                compared += 1;
            }
        }
        assert!(compared > 300, "{compared}");
    }

    #[test]
    fn a_non_finite_value_stops_the_sample_naming_the_quantity_and_the_time() {
        let (m, state) = model("pendulum.toml");
        let mut rec = Recording::of(&m).unwrap();
        let order = rec.order();
        let mut sys = Mechanism::new(&m);
        m.accelerations(0.25, &state.y, &mut sys.ws);
        sys.ws.acc[0][4] = f64::NAN;
        let err = rec
            .sample(&order, &m, &mut sys.ws, 0.25, &state.y)
            .unwrap_err();
        let name = &m.bodies[0].name;
        match err {
            crate::Error::Solver(jointplay_solver::Error::Diverged { time, message }) => {
                assert_eq!(time, 0.25);
                assert_eq!(
                    message,
                    format!("angular acceleration of body '{name}' became non-finite")
                );
            }
            other => panic!("{other}"),
        }
        // The failed sample is dropped whole.
        rec.truncate(0);
        assert!(rec.time.is_empty() && rec.channels.iter().all(|c| c.values.is_empty()));
    }

    /// The values of every dataset of a run file, by path, as f64 (flags too), with their shapes.
    fn datasets(g: &hdf5::Group, prefix: &str, out: &mut Vec<(String, Vec<usize>, Vec<f64>)>) {
        for name in g.member_names().unwrap() {
            let path = format!("{prefix}{name}");
            if let Ok(sub) = g.group(&name) {
                datasets(&sub, &format!("{path}/"), out);
                continue;
            }
            let ds = g.dataset(&name).unwrap();
            let v = match ds.read_raw::<f64>() {
                Ok(v) => v,
                Err(_) => ds
                    .read_raw::<u8>()
                    .unwrap()
                    .into_iter()
                    .map(f64::from)
                    .collect(),
            };
            out.push((path, ds.shape(), v));
        }
    }

    /// The datasets of the file at `p` (as [`datasets`] reads them), sorted by path.
    fn sorted_datasets(p: &Path) -> Vec<(String, Vec<usize>, Vec<f64>)> {
        let mut d = Vec::new();
        datasets(&hdf5::File::open(p).unwrap(), "", &mut d);
        d.sort_by(|x, y| x.0.cmp(&y.0));
        d
    }

    /// The same datasets in both lists: names, shapes and values bit for bit.
    fn assert_same_datasets(
        da: &[(String, Vec<usize>, Vec<f64>)],
        db: &[(String, Vec<usize>, Vec<f64>)],
    ) {
        assert_eq!(da.len(), db.len());
        for ((na, sa, va), (nb, sb, vb)) in da.iter().zip(db) {
            assert_eq!((na, sa), (nb, sb));
            assert!(
                va.iter().zip(vb).all(|(x, y)| x.to_bits() == y.to_bits()),
                "{na} differs"
            );
        }
    }

    /// Blocks that do not start a chunk (appended through HDF5's own filters) and blocks that do
    /// (packed by the program), in any mix, give the datasets of the run written at its end
    /// (names, shapes, values bit for bit), values rounded by quantity included.
    #[test]
    fn blocks_appended_at_any_row_give_the_run_written_at_its_end() {
        let (mut m, state) = model("pendulum.toml");
        m.settings.end_time = 5.0;
        m.outputs.significant_bits = jointplay_solver::model::Bits {
            default: Some(24),
            by_quantity: vec![("position".into(), None)],
        };
        let dir = tempfile::tempdir().unwrap();
        let file = PathBuf::from("pendulum.toml");
        let meta = Meta::of(&m, &file, "scene text", "test");
        let whole = simulate(&m, state, &mut |_| {}).unwrap();
        let a = crate::storage::run_file::write_run(&dir.path().join("a"), &meta, &whole).unwrap();
        let rec = &whole.recording;
        let n = rec.time.len();
        let mut writer = RunWriter::create(&dir.path().join("b"), &meta, rec).unwrap();
        // Rows 0-999 (packed), 1000-2047 (filters, ends at a chunk), 2048-4095 (packed),
        // 4096-4999 (packed, a partial chunk), 5000 (filters).
        for (from, to) in [
            (0, 1000),
            (1000, 2048),
            (2048, 4096),
            (4096, 5000),
            (5000, n),
        ] {
            let mut block = rec.clone();
            block.time = rec.time[from..to].to_vec();
            for (c, full) in block.channels.iter_mut().zip(&rec.channels) {
                let w = c.width();
                c.values = full.values[from * w..to * w].to_vec();
            }
            assert_eq!(writer.rows(), from);
            writer.append(&block, from == 4096).unwrap();
        }
        let b = writer.finish(&meta, &whole).unwrap();
        let (da, db) = (sorted_datasets(&a), sorted_datasets(&b));
        assert!(
            da.iter()
                .any(|d| d.0 == "bodies/bob/velocity" && d.1 == [n, 3])
        );
        assert_same_datasets(&da, &db);
    }

    /// A long streamed run's figures keep every excursion: of 100 000 samples fed in blocks, the
    /// kept rows stay within four times the bound, start with the first sample, are values the
    /// run took, and hold a one-sample spike up and down at its full height (the old every
    /// n-th sample drew a 92 kN impact as 36 kN).
    #[test]
    fn a_long_runs_figures_keep_every_excursion() {
        let (mut m, state) = model("pendulum.toml");
        m.settings.end_time = 25.0;
        let whole = simulate(&m, state, &mut |_| {}).unwrap().recording;
        let n1 = whole.time.len();
        let mut long = whole.clone();
        for k in 1..4 {
            long.time
                .extend(whole.time.iter().map(|t| t + 25.0 * k as f64 + 1.0));
            for (c, w) in long.channels.iter_mut().zip(&whole.channels) {
                c.values.extend_from_slice(&w.values);
            }
        }
        let n = long.time.len();
        let pos = long
            .channels
            .iter()
            .position(|c| c.dataset == "bodies/bob/position")
            .unwrap();
        let w = long.channels[pos].width();
        long.channels[pos].values[(2 * n1 + 17) * w + 1] = 1e3;
        long.channels[pos].values[(3 * n1 + 3) * w + 1] = -1e3;
        let block = |a: usize, b: usize| {
            let mut r = long.clone();
            r.time = long.time[a..b].to_vec();
            for c in &mut r.channels {
                let w = c.width();
                c.values = c.values[a * w..b * w].to_vec();
            }
            r
        };
        // As a streamed run declares it: its channels, no samples yet.
        let mut kept = Kept::new(&block(0, 0));
        for a in (0..n).step_by(STREAM_ROWS) {
            kept.add(&block(a, (a + STREAM_ROWS).min(n)));
        }
        let rows = kept.thin.time.len();
        assert!(kept.bucket >= 4, "{}", kept.bucket);
        assert!(
            (FIGURE_SAMPLES..=4 * FIGURE_SAMPLES + 2).contains(&rows),
            "{rows}"
        );
        assert!(kept.thin.time.windows(2).all(|t| t[0] <= t[1]));
        for (c, full) in kept.thin.channels.iter().zip(&long.channels) {
            if c.values.is_empty() {
                continue;
            }
            assert_eq!(c.values.len(), rows * c.width(), "{}", c.dataset);
            assert_eq!(
                c.values[..c.width()],
                full.values[..c.width()],
                "{}",
                c.dataset
            );
            let took: std::collections::HashSet<u64> =
                full.values.iter().map(|v| v.to_bits()).collect();
            assert!(
                c.values.iter().all(|v| took.contains(&v.to_bits())),
                "{}",
                c.dataset
            );
        }
        let y = kept.thin.channels[pos].column(1);
        assert!(y.contains(&1e3) && y.contains(&-1e3));
    }

    /// The farthest of candidate rows from a first one: per column, or as a whole vector.
    #[test]
    fn the_farthest_row_is_taken_per_column_or_as_a_vector() {
        let first = [0.0, 0.0];
        let cands: [&[f64]; 2] = [&[3.0, 0.0], &[-1.0, 2.0]];
        assert_eq!(farthest(&first, &cands, false), vec![0, 1]);
        // As a vector: |(3, 0)| = 3 > |(-1, 2)| = 2.24, so the first candidate, whole.
        assert_eq!(farthest(&first, &cands, true), vec![0, 0]);
    }

    /// A run written while it goes, over several appended blocks, holds the datasets (names,
    /// shapes, values bit for bit) and the attributes of the same run written at its end; what
    /// it keeps in memory is every sample of the figures' datasets (it is short).
    #[test]
    fn a_run_written_as_it_goes_is_the_run_written_at_its_end() {
        let (mut m, state) = model("pendulum.toml");
        // 25 001 samples: a dozen appended blocks, and more than twice FIGURE_SAMPLES.
        m.settings.end_time = 25.0;
        let dir = tempfile::tempdir().unwrap();
        let file = PathBuf::from("pendulum.toml");
        let meta = Meta::of(&m, &file, "scene text", "test");
        let whole = simulate(&m, state.clone(), &mut |_| {}).unwrap();
        let a = crate::storage::run_file::write_run(&dir.path().join("a"), &meta, &whole).unwrap();
        let (thin, w) =
            simulate_to_file(&m, state, &mut |_| {}, &dir.path().join("b"), &meta).unwrap();
        let n = whole.recording.time.len();
        assert!(n > 2 * FIGURE_SAMPLES, "{n}");
        assert!(n > 10 * STREAM_ROWS, "{n}");
        assert_eq!(w.samples, n);
        assert_eq!(w.path, dir.path().join("b/pendulum.h5"));
        assert!(!dir.path().join("b/pendulum.h5.partial").exists());
        let (fa, fb) = (
            hdf5::File::open(&a).unwrap(),
            hdf5::File::open(&w.path).unwrap(),
        );
        let (da, db) = (sorted_datasets(&a), sorted_datasets(&w.path));
        assert!(da.len() >= 17, "{}", da.len());
        assert_same_datasets(&da, &db);
        let names = |f: &hdf5::File| {
            let mut v = f.attr_names().unwrap();
            v.sort();
            v
        };
        assert_eq!(names(&fa), names(&fb));
        for k in ["steps_accepted", "rhs_evaluations"] {
            let r = |f: &hdf5::File| f.attr(k).unwrap().read_scalar::<u64>().unwrap();
            assert_eq!(r(&fa), r(&fb), "{k}");
        }
        let complete = |f: &hdf5::File| f.attr("complete").unwrap().read_scalar::<u8>().unwrap();
        assert_eq!((complete(&fa), complete(&fb)), (1, 1));
        // The figures' samples: all of them, below four times the bound.
        assert_eq!(w.bucket, 1);
        assert_eq!(thin.recording.time, whole.recording.time);
        for (c, full) in thin
            .recording
            .channels
            .iter()
            .zip(&whole.recording.channels)
        {
            if crate::storage::run::drawn(&c.dataset) {
                assert_eq!(c.values, full.values, "{}", c.dataset);
            } else {
                assert!(c.values.is_empty(), "{}", c.dataset);
            }
        }
        assert!(thin.recording.channel("bodies/bob/position").is_some());
        let max = |d: &str| {
            whole
                .recording
                .channel(d)
                .unwrap()
                .values
                .iter()
                .fold(0.0f64, |m, x| m.max(x.abs()))
        };
        assert_eq!(
            w.max_drift,
            Some((
                max("diagnostics/constraint_drift"),
                max("diagnostics/velocity_drift")
            ))
        );
    }

    /// A run records the radial eccentricity's rate beside it; it is the derivative of the
    /// recorded radial eccentricity. Checked against central differences of the samples over the
    /// slider-crank's first crank turn, impacts included: the difference quotient's error is
    /// (dt^2 / 6) times the third derivative, relative (w dt)^2 / 6 = 5e-6 at the crank's
    /// 524 rad/s and dt = 1e-5 s, more through the impacts' sharp turns; so half of the samples
    /// must agree to 1e-3 of the rate's typical size, far below the 100 % a wrong frame or sign
    /// would give.
    #[test]
    fn the_radial_eccentricity_rate_is_the_derivative_of_the_radial_eccentricity() {
        let (mut m, state) = slider_crank(0.012);
        m.outputs.interval = 1e-5;
        let run = simulate(&m, state, &mut |_| {}).unwrap().recording;
        let ch = |d: &str| run.channel(d).unwrap();
        let (e, r) = (
            ch("joints/piston_pin/radial_eccentricity"),
            ch("joints/piston_pin/radial_eccentricity_rate"),
        );
        assert_eq!(r.unit, "m/s");
        let t = &run.time;
        let (mut errors, mut sizes) = (Vec::new(), Vec::new());
        for i in 1..t.len() - 1 {
            for k in 0..2 {
                let d =
                    (e.values[2 * (i + 1) + k] - e.values[2 * (i - 1) + k]) / (t[i + 1] - t[i - 1]);
                errors.push((d - r.values[2 * i + k]).abs());
                sizes.push(r.values[2 * i + k].abs());
            }
        }
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let (err, size) = (median(&mut errors), median(&mut sizes));
        assert!(size > 1e-3, "the journal barely moves: {size} m/s");
        assert!(
            err < 1e-3 * size,
            "median error {err} m/s against {size} m/s"
        );
    }

    /// The clearance slider-crank up to `end_time` s.
    fn slider_crank(end_time: f64) -> (Model, State) {
        let (mut m, state) = model("slider-crank-clearance.toml");
        m.settings.end_time = end_time;
        (m, state)
    }

    /// The run of `m` from `state` recorded in line and written at its end to `dir/a`: the
    /// files' metadata, the run and its file.
    fn in_line<'m>(m: &'m Model, state: &State, dir: &Path) -> (Meta<'m>, RunResult, PathBuf) {
        let meta = Meta::of(m, Path::new("slider-crank-clearance.toml"), "text", "test");
        let whole = simulate(m, state.clone(), &mut |_| {}).unwrap();
        let a = crate::storage::run_file::write_run(&dir.join("a"), &meta, &whole).unwrap();
        (meta, whole, a)
    }

    /// The writer thread evaluates the recording from the states and onset histories it is
    /// handed, in a workspace of its own: on a clearance joint's impacts and flights (the
    /// slider-crank, over three blocks) the run written as it goes holds the values of the run
    /// recorded on the integrating thread, bit for bit, and the same statistics.
    #[test]
    fn a_clearance_run_written_as_it_goes_is_the_run_recorded_in_line() {
        let dir = tempfile::tempdir().unwrap();
        let (m, state) = slider_crank(0.05);
        let (meta, whole, a) = in_line(&m, &state, dir.path());
        let (run, w) =
            simulate_to_file(&m, state, &mut |_| {}, &dir.path().join("b"), &meta).unwrap();
        let n = whole.recording.time.len();
        assert!(n > 2 * STREAM_ROWS, "{n}");
        assert_eq!(w.samples, n);
        assert!(run.stopped.is_none() && whole.stopped.is_none());
        assert_eq!(run.stats.rhs_evals, whole.stats.rhs_evals);
        // The pin both flies and touches in the span: the onset history is met open and closed.
        let force = whole
            .recording
            .channels
            .iter()
            .find(|c| c.dataset.ends_with("normal_force"));
        let force = &force.unwrap().values;
        assert!(force.iter().any(|&f| f > 0.0) && force.contains(&0.0));
        let (da, db) = (sorted_datasets(&a), sorted_datasets(&w.path));
        assert!(da.len() > 20, "{}", da.len());
        assert_same_datasets(&da, &db);
    }

    /// Parts the integrating side evaluates while the writer is behind (here every other one),
    /// between parts the writer evaluates, give the run recorded in line, bit for bit: the
    /// clearance slider-crank, its pin flying and touching, over five blocks (the integrating
    /// side evaluates every second part, the writer's threads the last).
    #[test]
    fn parts_evaluated_while_the_writer_is_behind_give_the_run_recorded_in_line() {
        let dir = tempfile::tempdir().unwrap();
        let (m, state) = slider_crank(0.1);
        let (meta, whole, a) = in_line(&m, &state, dir.path());
        let mut assembled = state;
        m.assemble(&mut assembled).unwrap();
        let all = states(&m, &assembled);
        assert_eq!(all.len(), whole.recording.time.len());
        assert!(all.len() > 4 * STREAM_ROWS, "{}", all.len());
        let rec = Recording::of(&m).unwrap();
        let file = RunWriter::open(&dir.path().join("b"), &meta).unwrap();
        let mut sink = Stream::new(&m, file, &rec);
        sink.probe.helps = Some(|b| b % 2 == 1);
        for (t, y, onset) in &all {
            assert!(sink.push(*t, y, onset));
        }
        assert!(sink.send(true));
        let full = all.len() / PART_ROWS;
        assert_eq!((sink.probe.parts, sink.probe.helped), (full + 1, full / 2));
        let (writer, kept, stopped) = sink.close().unwrap().unwrap();
        assert!(stopped.is_none());
        assert_eq!(kept.rows, all.len());
        let b = writer.finish(&meta, &whole).unwrap();
        assert_same_datasets(&sorted_datasets(&a), &sorted_datasets(&b));
    }

    /// The states of a run from `state` (assembled) at its sample times, with their onset
    /// histories, as the integration hands them to a [`Stream`].
    fn states(m: &Model, state: &State) -> Vec<(f64, Vec<f64>, Vec<f64>)> {
        let mut y = state.y.clone();
        let mut sys = Mechanism::new(m);
        let mut out = Vec::new();
        jointplay_solver::ode::integrate(
            &mut sys,
            m.settings.method,
            0.0,
            &mut y,
            m.settings.end_time,
            &m.sample_times(),
            |sys, t, y| {
                out.push((t, y.to_vec(), sys.ws.onset.clone()));
                Flow::Continue
            },
        )
        .unwrap();
        out
    }

    /// A sample whose recorded value is not finite (a state with a velocity so large that the
    /// accelerations overflow) stops the run where it is, in a part evaluated beside the
    /// integration, in one the integrating side evaluated while the writer was behind and in
    /// the last part, evaluated by every thread after the other samples of its block: the
    /// samples before it are written, none after, and the stop names the quantity and the time.
    #[test]
    fn a_non_finite_recorded_value_stops_a_run_written_as_it_goes_at_its_sample() {
        let (mut m, state) = model("pendulum.toml");
        m.settings.end_time = 8.0;
        let all = states(&m, &state);
        assert!(all.len() > 3 * STREAM_ROWS + 500, "{}", all.len());
        let dir = tempfile::tempdir().unwrap();
        let meta = Meta::of(&m, Path::new("pendulum.toml"), "text", "test");
        // In the first block (which the writer evaluates), in a part of the third (evaluated by
        // the integrating side, as when the writer is behind: the run stops at once) and in the
        // last part (thirty samples before the end), after the other samples of its block.
        let last_part = all.len() - 30;
        let last_start = (all.len() - 1) / PART_ROWS * PART_ROWS;
        assert!(last_part >= last_start && !last_start.is_multiple_of(STREAM_ROWS));
        for bad in [1000, 2 * STREAM_ROWS + 500, last_part] {
            let rec = Recording::of(&m).unwrap();
            let file = RunWriter::open(&dir.path().join(bad.to_string()), &meta).unwrap();
            let mut sink = Stream::new(&m, file, &rec);
            let helped = bad == 2 * STREAM_ROWS + 500;
            if helped {
                sink.probe.helps = Some(|b| b == (2 * STREAM_ROWS + 500) / PART_ROWS);
            }
            let mut pushed = 0;
            for (i, (t, y, onset)) in all.iter().enumerate() {
                let mut y = y.clone();
                if i == bad {
                    let v = y.len() / 2;
                    y[v..].iter_mut().for_each(|x| *x = 1e300);
                }
                pushed += 1;
                if !sink.push(*t, &y, onset) {
                    break;
                }
            }
            sink.send(true);
            let (writer, kept, stopped) = sink.close().unwrap().unwrap();
            let stopped = stopped.expect("the run stops at the bad sample");
            assert_eq!(stopped.time, all[bad].0, "{bad}");
            assert!(
                stopped.message.ends_with("became non-finite"),
                "{}",
                stopped.message
            );
            assert_eq!(writer.rows(), bad);
            assert_eq!(kept.rows, bad);
            // The integration learns of it when it hands over a part, at most WAITING + 1 parts
            // after the one that failed (those wait in the channel meanwhile).
            assert!(
                pushed <= (bad / PART_ROWS + WAITING + 2) * PART_ROWS,
                "{pushed}"
            );
            if bad < STREAM_ROWS {
                assert!(pushed < all.len(), "{pushed}");
            }
            if helped {
                assert_eq!(sink.probe.helped, 1);
                assert_eq!(pushed, (bad / PART_ROWS + 1) * PART_ROWS);
            }
            writer.discard();
        }
    }

    /// With `output.significant_bits`, both writers (the run written at its end, as a study case
    /// is, and the run written as it goes) store every recorded value rounded to the bits of its
    /// quantity, exactly [`crate::storage::bitround::round`] of the value computed, and mark each rounded
    /// dataset with its bits and the file with the fewest; a quantity given every bit, the sample
    /// times and the final state are written exactly.
    #[test]
    fn recorded_values_keep_the_significant_bits_asked_for_in_both_writers() {
        let (mut m, state) = model("pendulum.toml");
        // 5 001 samples: three appended blocks.
        m.settings.end_time = 5.0;
        m.outputs.significant_bits = jointplay_solver::model::Bits {
            default: Some(30),
            by_quantity: vec![
                ("position".into(), None),
                ("reaction_force".into(), Some(16)),
            ],
        };
        let want_bits = |dataset: &str| match dataset.rsplit('/').next() {
            Some("position") => None,
            Some("reaction_force") => Some(16),
            _ => Some(30),
        };
        let dir = tempfile::tempdir().unwrap();
        let file = PathBuf::from("pendulum.toml");
        let meta = Meta::of(&m, &file, "scene text", "test");
        let whole = simulate(&m, state.clone(), &mut |_| {}).unwrap();
        assert_eq!(whole.recording.significant_bits(), Some(16));
        let a = crate::storage::run_file::write_run(&dir.path().join("a"), &meta, &whole).unwrap();
        let (_, w) =
            simulate_to_file(&m, state, &mut |_| {}, &dir.path().join("b"), &meta).unwrap();
        let mut exact = whole.clone();
        for c in &mut exact.recording.channels {
            c.bits = None;
        }
        let c = crate::storage::run_file::write_run(&dir.path().join("c"), &meta, &exact).unwrap();
        let read = |p: &Path| {
            let f = hdf5::File::open(p).unwrap();
            let mut d = Vec::new();
            datasets(&f, "", &mut d);
            d.sort_by(|x, y| x.0.cmp(&y.0));
            (f, d)
        };
        let ((fa, da), (fb, db), (fc, dc)) = (read(&a), read(&w.path), read(&c));
        let bits = |l: &hdf5::Location| {
            l.attr("significant_bits")
                .and_then(|a| a.read_scalar::<u64>())
                .ok()
                .map(|b| b as u32)
        };
        assert_eq!(
            (bits(&fa), bits(&fb), bits(&fc)),
            (Some(16), Some(16), None)
        );
        let (mut rounded, mut kinds) = (0, std::collections::BTreeSet::new());
        for (((na, _, va), (nb, _, vb)), (nc, _, vc)) in da.iter().zip(&db).zip(&dc) {
            assert_eq!((na, na), (nb, nc));
            let flag = fc.dataset(nc).unwrap().dtype().unwrap().size() == 1;
            let want = match whole.recording.channel(nc) {
                Some(_) if !flag => {
                    let b = want_bits(nc);
                    assert_eq!(bits(&fa.dataset(na).unwrap()), b, "{na}");
                    assert_eq!(bits(&fb.dataset(nb).unwrap()), b, "{nb}");
                    kinds.insert(b);
                    let mut v = vc.clone();
                    if let Some(b) = b {
                        rounded += 1;
                        crate::storage::bitround::round(&mut v, b);
                    }
                    v
                }
                _ => vc.clone(),
            };
            for (got, name) in [(va, na), (vb, nb)] {
                assert_eq!(got.len(), want.len(), "{name}");
                assert!(
                    got.iter()
                        .zip(&want)
                        .all(|(x, y)| x.to_bits() == y.to_bits()),
                    "{name} differs"
                );
            }
        }
        // Every kind of quantity was met: kept, rounded to 16 and to 30 bits.
        assert_eq!(kinds.len(), 3, "{kinds:?}");
        for name in ["time", "final_state", "final_time"] {
            assert!(bits(&fa.dataset(name).unwrap()).is_none(), "{name}");
            assert!(bits(&fb.dataset(name).unwrap()).is_none(), "{name}");
        }
        assert!(rounded >= 10, "{rounded}");
        assert!(da.iter().any(|d| d.0 == "time") && da.iter().any(|d| d.0 == "final_state"));
        // What the rounding is for: the zeroed low bytes compress to almost nothing.
        let size = |p: &Path| std::fs::metadata(p).unwrap().len();
        assert!(size(&a) < size(&c), "{} {}", size(&a), size(&c));
    }

    /// A stop requested halfway ends the run with the step of the next sample: the samples up
    /// to it are kept whole and equal those of the run to its end, and the run says it was
    /// interrupted.
    #[test]
    fn a_stopped_run_keeps_the_samples_before_the_stop() {
        let (m, state) = model("pendulum.toml");
        let whole = simulate(&m, state.clone(), &mut |_| {}).unwrap();
        let stop = Stop::new();
        let part = simulate_until(
            &m,
            state,
            &mut |f| {
                if f > 0.5 {
                    stop.request()
                }
            },
            &stop,
        )
        .unwrap();
        assert!(part.interrupted() && whole.stopped.is_none());
        let n = part.recording.time.len();
        assert!(n > 100 && n < whole.recording.time.len() / 2 + 10, "{n}");
        assert_eq!(part.recording.time[..], whole.recording.time[..n]);
        for (a, b) in part
            .recording
            .channels
            .iter()
            .zip(&whole.recording.channels)
        {
            assert_eq!(a.values.len(), n * a.width());
            assert_eq!(a.values[..], b.values[..a.values.len()], "{}", a.dataset);
        }
        let err = part.finished().unwrap_err().to_string();
        assert!(err.starts_with("interrupted on request at t = "), "{err}");
    }
}
