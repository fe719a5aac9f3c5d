//! The hybrid state ([`HybridState`]: time, continuous state, contact-onset history, guard flags
//! and integrator memory) in HDF5 files, so that a run can be saved, loaded and continued as if
//! it had never stopped (see [`jointplay_solver::state`]).
//!
//! Layout, in the group that holds a run's results (the root of a run file or of a single
//! analysis run; `/sweep` of a sweep, where every dataset gains a leading job dimension):
//!
//! | dataset | shape | unit | content |
//! |---|---|---|---|
//! | `final_state` | dim | SI | the continuous state y at the end time |
//! | `final_time` | scalar (sweep: jobs) | s | the end time |
//! | `final_onset` | contacts | m/s | approach velocity at the onset of each contact, NaN out of contact |
//! | `final_warned` | clearance joints | 1 | 1 where the step-size guard has warned about the joint |
//! | `final_stepper` | 5 | mixed | integrator memory: grid origin (s), grid step (s), grid points reached, next adaptive step (s), last error norm |
//!
//! `final_onset` and `final_warned` have length 0 for a flow without contacts (a built-in
//! system). `final_stepper` holds NaN for the parts a method did not use (the grid of an
//! adaptive method, the next step of a fixed-step one).

use std::path::Path;

use hdf5::Group;
use ndarray::{Array1, Array2, s};

use jointplay_solver::state::{HybridState, StepperMemory};

use crate::storage::h5::{create_nan, describe, h5err, write_column, write1};
use crate::{Error, Result};

/// Column descriptions of `final_stepper`, in order.
const STEPPER: &str = "integrator memory: [grid origin (s), grid step (s), grid points reached, \
                       next adaptive step (s), last error norm]";

pub(crate) fn stepper_row(m: &StepperMemory) -> [f64; 5] {
    [
        m.grid_origin,
        m.grid_step,
        m.grid_steps as f64,
        m.next_step,
        m.last_error,
    ]
}

pub(crate) fn stepper_from(v: &[f64]) -> hdf5::Result<StepperMemory> {
    let [grid_origin, grid_step, steps, next_step, last_error] = <[f64; 5]>::try_from(v)
        .map_err(|_| hdf5::Error::from(format!("final_stepper: {} values for 5", v.len())))?;
    if !(steps >= 0.0 && steps.fract() == 0.0 && steps < 2f64.powi(53)) {
        return Err(format!("final_stepper: grid points reached {steps} is not a count").into());
    }
    Ok(StepperMemory {
        grid_origin,
        grid_step,
        grid_steps: steps as u64,
        next_step,
        last_error,
    })
}

/// Writes `state` into `g` (layout in the module documentation).
pub fn write_state(g: &Group, state: &HybridState) -> hdf5::Result<()> {
    write1(
        g,
        "final_state",
        &state.y,
        "SI",
        "state vector at the end time",
    )?;
    let t = g.new_dataset::<f64>().create("final_time")?;
    t.write_scalar(&state.t)?;
    describe(&t, Some("s"), "time of the final state")?;
    write1(
        g,
        "final_onset",
        &state.onset,
        "m/s",
        "approach velocity at the onset of each contact at the end time (NaN: out of contact)",
    )?;
    let warned: Vec<u8> = state.warned.iter().map(|&w| u8::from(w)).collect();
    write_column(
        g,
        "final_warned",
        &warned,
        Some("1"),
        "1 where the step-size guard has warned about the clearance joint",
    )?;
    write1(
        g,
        "final_stepper",
        &stepper_row(&state.stepper),
        "mixed",
        STEPPER,
    )
}

/// Reads the state [`write_state`] wrote into `g`.
pub fn read_state(g: &Group) -> hdf5::Result<HybridState> {
    let warned: Vec<u8> = g.dataset("final_warned")?.read_raw()?;
    Ok(HybridState {
        t: g.dataset("final_time")?.read_scalar()?,
        y: g.dataset("final_state")?.read_raw()?,
        onset: g.dataset("final_onset")?.read_raw()?,
        warned: warned.iter().map(|&w| w != 0).collect(),
        stepper: stepper_from(&g.dataset("final_stepper")?.read_raw::<f64>()?)?,
    })
}

/// The final state of the run file `path` (written by `jointplay run SCENE`), to continue the
/// run from: a complete run, or one stopped on request (attribute `interrupted = 1`). A run
/// that failed is refused: its last state is where it failed.
pub fn read_run_file(path: &Path) -> Result<HybridState> {
    let e = h5err(path);
    let file = hdf5::File::open(path).map_err(&e)?;
    if file.attr("kind").is_ok() {
        return Err(Error::Io {
            file: path.to_path_buf(),
            message: "an analysis or work-precision file: a run continues from a run file \
                      written by `jointplay run SCENE`"
                .into(),
        });
    }
    let complete: u8 = file
        .attr("complete")
        .and_then(|a| a.read_scalar())
        .map_err(|_| Error::Io {
            file: path.to_path_buf(),
            message: "not a run file of jointplay (no 'complete' attribute)".into(),
        })?;
    // A run stopped on request (SIGINT, SIGTERM) ended between two steps: its final state is
    // one the run passed through, and continuing from it is the run that was not stopped.
    let interrupted = file
        .attr("interrupted")
        .and_then(|a| a.read_scalar::<u8>())
        .is_ok_and(|v| v == 1);
    if complete != 1 && !interrupted {
        return Err(Error::Io {
            file: path.to_path_buf(),
            message: "the run stopped before its end time: its last state is where it failed, \
                      not a state to continue from"
                .into(),
        });
    }
    let state = read_state(&file).map_err(|err| Error::Io {
        file: path.to_path_buf(),
        message: format!(
            "no final state to continue from ({err}); files written before the \
                          hybrid state was saved cannot be continued"
        ),
    })?;
    // A damaged or edited file: a run from t = -1e300 to the end time could never finish.
    if !state.t.is_finite() {
        return Err(Error::Io {
            file: path.to_path_buf(),
            message: format!("final_time: {} s is not a time to continue from", state.t),
        });
    }
    if !state.y.iter().all(|v| v.is_finite()) {
        return Err(Error::Io {
            file: path.to_path_buf(),
            message: "final_state: not finite, not a state to continue from".into(),
        });
    }
    Ok(state)
}

/// Sizes of the state rows of a sweep: the continuous state, the contacts and the clearance
/// joints of its flow.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StateShape {
    pub dim: usize,
    pub contacts: usize,
    pub clearances: usize,
}

/// Creates the per-job state datasets of a sweep with `jobs` rows (NaN, or 0, until a job is
/// written; `/sweep/done` says which rows hold a state).
pub fn create_rows(g: &Group, jobs: usize, shape: StateShape) -> hdf5::Result<()> {
    let nan = |name: &str, cols: usize, unit: &str, desc: &str| {
        create_nan(g, name, &[jobs, cols], unit, desc)
    };
    nan(
        "final_state",
        shape.dim,
        "SI",
        "state vector at the end time, per job",
    )?;
    create_nan(
        g,
        "final_time",
        &[jobs],
        "s",
        "time of the final state, per job",
    )?;
    nan(
        "final_onset",
        shape.contacts,
        "m/s",
        "approach velocity at the onset of each contact at the end time, per job (NaN: out of \
         contact)",
    )?;
    let w = g
        .new_dataset::<u8>()
        .shape((jobs, shape.clearances))
        .create("final_warned")?;
    describe(
        &w,
        Some("1"),
        "1 where the step-size guard has warned about the clearance joint, per job",
    )?;
    nan("final_stepper", 5, "mixed", &format!("{STEPPER}, per job"))
}

fn put_row<T: hdf5::H5Type + Clone>(g: &Group, name: &str, j: usize, v: &[T]) -> hdf5::Result<()> {
    let ds = g.dataset(name)?;
    let cols = ds.shape()[1];
    if v.len() != cols {
        return Err(format!("{name}: {} values for {cols} columns", v.len()).into());
    }
    if cols == 0 {
        return Ok(());
    }
    ds.write_slice(&Array1::from(v.to_vec()), s![j, ..])
}

fn get_row<T: hdf5::H5Type + Clone>(g: &Group, name: &str, j: usize) -> hdf5::Result<Vec<T>> {
    let ds = g.dataset(name)?;
    if ds.shape()[1] == 0 {
        return Ok(Vec::new());
    }
    let a: Array2<T> = ds.read_slice(s![j..j + 1, ..])?;
    Ok(a.iter().cloned().collect())
}

/// Writes job `j`'s final state into the rows [`create_rows`] made.
pub fn write_row(g: &Group, j: usize, state: &HybridState) -> hdf5::Result<()> {
    put_row(g, "final_state", j, &state.y)?;
    g.dataset("final_time")?
        .write_slice(&Array1::from(vec![state.t]), s![j..j + 1])?;
    put_row(g, "final_onset", j, &state.onset)?;
    let warned: Vec<u8> = state.warned.iter().map(|&w| u8::from(w)).collect();
    put_row(g, "final_warned", j, &warned)?;
    put_row(g, "final_stepper", j, &stepper_row(&state.stepper))
}

/// Reads job `j`'s final state; an error for a job whose state was never written.
pub fn read_row(g: &Group, j: usize) -> hdf5::Result<HybridState> {
    let t: Array1<f64> = g.dataset("final_time")?.read_slice(s![j..j + 1])?;
    if t[0].is_nan() {
        return Err(format!("final_time: job {j} has no final state (not done)").into());
    }
    let warned: Vec<u8> = get_row(g, "final_warned", j)?;
    Ok(HybridState {
        t: t[0],
        y: get_row(g, "final_state", j)?,
        onset: get_row(g, "final_onset", j)?,
        warned: warned.iter().map(|&w| w != 0).collect(),
        stepper: stepper_from(&get_row::<f64>(g, "final_stepper", j)?)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> HybridState {
        HybridState {
            t: 2.0000000000000004,
            y: vec![1.0, -0.0, 1e-300, f64::MIN_POSITIVE / 3.0],
            onset: vec![f64::NAN, -0.0123, f64::NAN],
            warned: vec![true, false],
            stepper: StepperMemory {
                grid_origin: 0.0,
                grid_step: 1e-4,
                grid_steps: 20_000,
                next_step: f64::NAN,
                last_error: 0.37,
            },
        }
    }

    fn bits(s: &HybridState) -> Vec<u64> {
        let m = &s.stepper;
        std::iter::once(s.t)
            .chain(s.y.iter().copied())
            .chain(s.onset.iter().copied())
            .chain(stepper_row(m))
            .map(f64::to_bits)
            .chain(s.warned.iter().map(|&w| u64::from(w)))
            .collect()
    }

    #[test]
    fn a_state_survives_the_file_bit_for_bit() {
        let dir = tempfile_dir();
        let path = dir.join("state.h5");
        let s0 = sample();
        let mut s1 = s0.clone();
        s1.t = 4.0;
        s1.onset = vec![0.5, f64::NAN, f64::NAN];
        {
            let f = hdf5::File::create(&path).unwrap();
            write_state(&f, &s0).unwrap();
            let g = f.create_group("sweep").unwrap();
            let shape = StateShape {
                dim: 4,
                contacts: 3,
                clearances: 2,
            };
            create_rows(&g, 3, shape).unwrap();
            write_row(&g, 2, &s1).unwrap();
            write_row(&g, 0, &s0).unwrap();
        }
        let f = hdf5::File::open(&path).unwrap();
        assert_eq!(bits(&read_state(&f).unwrap()), bits(&s0));
        let g = f.group("sweep").unwrap();
        assert_eq!(bits(&read_row(&g, 0).unwrap()), bits(&s0));
        assert_eq!(bits(&read_row(&g, 2).unwrap()), bits(&s1));
        // A row never written is not a state anyone could continue from.
        let e = read_row(&g, 1).unwrap_err().to_string();
        assert!(e.contains("job 1 has no final state"), "{e}");
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn a_flow_without_contacts_stores_empty_memory() {
        let dir = tempfile_dir();
        let path = dir.join("empty.h5");
        let s0 = HybridState::new(0.5, vec![1.0, 2.0]);
        {
            let f = hdf5::File::create(&path).unwrap();
            write_state(&f, &s0).unwrap();
            let g = f.create_group("sweep").unwrap();
            let shape = StateShape {
                dim: 2,
                contacts: 0,
                clearances: 0,
            };
            create_rows(&g, 2, shape).unwrap();
            write_row(&g, 1, &s0).unwrap();
        }
        let f = hdf5::File::open(&path).unwrap();
        let r = read_state(&f).unwrap();
        assert_eq!(bits(&r), bits(&s0));
        assert!(r.onset.is_empty() && r.warned.is_empty());
        let g = f.group("sweep").unwrap();
        assert_eq!(bits(&read_row(&g, 1).unwrap()), bits(&s0));
        std::fs::remove_dir_all(dir).unwrap();
    }

    fn tempfile_dir() -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!(
            "jointplay-hybrid-{}-{:?}",
            std::process::id(),
            std::thread::current().id()
        ));
        std::fs::create_dir_all(&d).unwrap();
        d
    }
}
