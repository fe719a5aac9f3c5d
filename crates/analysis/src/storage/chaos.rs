//! The chaos measures in HDF5: a single run's `/chaos` group, the per-value rows of a sweep
//! (`/sweep/chaos`), and the summary `jointplay` prints from a written file (layout in
//! book/src/reference/hdf5.md). The measures themselves are [`crate::measures::chaos`].

use crate::measures::chaos::{CLASS_NAMES, Chaos, ChaosSpec, Class};
use crate::measures::indicator::Number;
use crate::measures::registry::INDICATORS;
use crate::storage::h5::{
    create_nan, f64_attr, str_attr, u8_attr_set, u64_attr, write_table, write1,
};

/// Writes the measures of a single run into the group `/chaos` (layout in book/src/reference/hdf5.md).
pub(crate) fn write_single(file: &hdf5::File, c: &Chaos) -> hdf5::Result<()> {
    let g = file.create_group("chaos")?;
    write_class(&g, c.class)?;
    if let Some(s) = &c.spectrum {
        let l = g.create_group("lyapunov")?;
        write1(
            &l,
            "exponents",
            &s.exponents,
            "1/s",
            "Lyapunov exponents of the flow, largest first",
        )?;
        write1(
            &l,
            "stderr",
            &s.stderr,
            "1/s",
            "batch-means standard errors of the exponents",
        )?;
        write1(
            &l,
            "map_exponents",
            &s.map_exponents(),
            "1",
            "exponents of the stroboscopic map, per iteration: the flow's times the period",
        )?;
        write1(
            &l,
            "history_time",
            &s.history_t,
            "s",
            "times of the re-orthonormalisations",
        )?;
        let flat: Vec<f64> = s.history.iter().flatten().copied().collect();
        write_table(
            &l,
            "history",
            &flat,
            s.exponents.len(),
            "1/s",
            "running estimate of every exponent at each re-orthonormalisation",
        )?;
        f64_attr(&l, "averaging_time", s.time)?;
        f64_attr(&l, "period", s.period)?;
        u64_attr(&l, "phase_dim", s.phase_dim as u64)?;
        u64_attr(&l, "rhs_evals", s.rhs_evals)?;
        str_attr(&l, "jvp", s.jvp)?;
        if let Some(d) = s.mean_divergence {
            f64_attr(&l, "mean_divergence", d)?;
        }
        // A change of lambda_1 while it averaged (crate::measures::lyapunov::drift): where, and
        // the two means.
        if let Some(d) = &s.drift {
            f64_attr(&l, "drift_time", d.time)?;
            f64_attr(&l, "lambda_1_before", d.before)?;
            f64_attr(&l, "lambda_1_after", d.after)?;
            f64_attr(&l, "drift_statistic", d.statistic)?;
            f64_attr(&l, "drift_critical", d.critical)?;
        }
        // Where the Lyapunov run left the trajectory (it goes on from the analysis run's end):
        // a run continued from here starts on what the motion settled to.
        crate::storage::hybrid::write_state(&l.create_group("end")?, &s.end)?;
        if let Some((v, e, h)) = &s.two_trajectory {
            f64_attr(&l, "two_trajectory", *v)?;
            f64_attr(&l, "two_trajectory_stderr", *e)?;
            write1(
                &l,
                "two_trajectory_history",
                h,
                "1/s",
                "running two-trajectory estimate of lambda_1",
            )?;
        }
    }
    for r in &c.readings {
        let g0 = g.create_group(r.key)?;
        for (name, v) in &r.attributes {
            match *v {
                Number::Real(x) => f64_attr(&g0, name, x)?,
                Number::Flag(b) => u8_attr_set(&g0, name, u8::from(b))?,
                Number::Count(n) => u64_attr(&g0, name, n)?,
            }
        }
    }
    Ok(())
}

fn write_class(g: &hdf5::Group, class: Class) -> hdf5::Result<()> {
    str_attr(g, "class", class.name())
}

/// Creates the per-value datasets of a sweep's measures in `/sweep/chaos` (`n` values, `k`
/// exponents), NaN until a value is written.
pub(crate) fn create_rows(g: &hdf5::Group, n: usize, spec: &ChaosSpec) -> hdf5::Result<()> {
    let c = g.create_group("chaos")?;
    c.new_dataset::<u8>().shape(n).create("class")?;
    let names: Vec<String> = CLASS_NAMES.iter().map(|s| s.to_string()).collect();
    let ds = c.dataset("class")?;
    str_attr(&ds, "names", &names.join(","))?;
    str_attr(
        &ds,
        "description",
        "class code per value: 0 undetermined, 1 periodic, 2 quasi-periodic, 3 chaotic",
    )?;
    if let Some(l) = &spec.lyapunov {
        let k = l.exponents;
        create_nan(
            &c,
            "exponents",
            &[n, k],
            "1/s",
            "Lyapunov exponents per value, largest first",
        )?;
        create_nan(
            &c,
            "stderr",
            &[n, k],
            "1/s",
            "their batch-means standard errors",
        )?;
        create_nan(
            &c,
            "map_exponents",
            &[n, k],
            "1",
            "exponents of the stroboscopic map (per iteration)",
        )?;
        if l.two_trajectory {
            create_nan(
                &c,
                "two_trajectory",
                &[n, 2],
                "1/s",
                "two-trajectory lambda_1 and its standard error",
            )?;
        }
    }
    for asked in &spec.indicators {
        let row = asked.indicator.row();
        create_nan(&c, row.name, &[n], row.unit, row.description)?;
    }
    Ok(())
}

/// The right-hand-side evaluations of a single run's Lyapunov run in the analysis file `path`
/// (None when it has none): the analysis run's own are the file's `rhs_evals`.
pub fn lyapunov_rhs_evals(path: &std::path::Path) -> crate::Result<Option<u64>> {
    let file = hdf5::File::open(path).map_err(crate::storage::h5::h5err(path))?;
    Ok(file
        .group("chaos/lyapunov")
        .ok()
        .and_then(|l| crate::storage::h5::read_attr::<u64>(&l, "rhs_evals").ok()))
}

/// Lines for the program's summary of the chaos measures in the analysis file `path` (none when
/// it has none).
pub fn summary(path: &std::path::Path) -> crate::Result<Vec<String>> {
    let e = crate::storage::h5::h5err(path);
    let file = hdf5::File::open(path).map_err(&e)?;
    let mut out = Vec::new();
    let list = |v: &[f64], digits: usize| {
        v.iter()
            .map(|x| format!("{x:.digits$}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    if let Ok(c) = file.group("chaos") {
        if let Ok(l) = c.group("lyapunov") {
            let ex = l
                .dataset("exponents")
                .and_then(|d| d.read_raw::<f64>())
                .map_err(&e)?;
            let se = l
                .dataset("stderr")
                .and_then(|d| d.read_raw::<f64>())
                .map_err(&e)?;
            let mu = l
                .dataset("map_exponents")
                .and_then(|d| d.read_raw::<f64>())
                .map_err(&e)?;
            out.push(format!(
                "lyapunov     {} 1/s (+- {})",
                list(&ex, 4),
                list(&se, 4)
            ));
            out.push(format!("map          {} per period", list(&mu, 4)));
            // How long the estimate averaged: the whole `periods`, or less when `until_stderr`
            // stopped it.
            if let (Ok(t), Ok(p)) = (
                crate::storage::h5::read_attr::<f64>(&l, "averaging_time"),
                crate::storage::h5::read_attr::<f64>(&l, "period"),
            ) {
                out.push(format!("averaged     {t:.6} s ({:.1} periods)", t / p));
            }
            let at = |n: &str| crate::storage::h5::read_attr::<f64>(&l, n);
            if let (Ok(t), Ok(a), Ok(b), Ok(d), Ok(c)) = (
                at("drift_time"),
                at("lambda_1_before"),
                at("lambda_1_after"),
                at("drift_statistic"),
                at("drift_critical"),
            ) {
                out.push(format!(
                    "drift        lambda_1's batch estimates change near t = {t:.6} s: {a:.4} 1/s \
                     before, {b:.4} after (CUSUM {d:.2} > {c:.2}); unless the strobe points \
                     repeat, not one motion: the value after is that of the motion it settled \
                     to (state at the end: /chaos/lyapunov/end)"
                ));
            }
            if let (Ok(v), Ok(s)) = (
                crate::storage::h5::read_attr::<f64>(&l, "two_trajectory"),
                crate::storage::h5::read_attr::<f64>(&l, "two_trajectory_stderr"),
            ) {
                out.push(format!("two traj.    {v:.4} +- {s:.4} 1/s"));
            }
        }
        for i in INDICATORS {
            if let Ok(z) = c.group(i.key()) {
                let v = crate::storage::h5::read_attr::<f64>(&z, i.row().name).map_err(&e)?;
                out.push(i.line(v));
            }
        }
        out.push(format!(
            "class        {}",
            crate::storage::h5::read_str(&c, "class").map_err(&e)?
        ));
    } else if let Ok(c) = file.group("sweep/chaos") {
        let class = c
            .dataset("class")
            .and_then(|d| d.read_raw::<u8>())
            .map_err(&e)?;
        let done = file
            .dataset("sweep/done")
            .and_then(|d| d.read_raw::<u8>())
            .map_err(&e)?;
        let mut counts = [0usize; 4];
        for (c, d) in class.iter().zip(&done) {
            if *d == 1 {
                counts[(*c as usize).min(3)] += 1;
            }
        }
        out.push(format!(
            "classes      {} periodic, {} quasi-periodic, {} chaotic, {} undetermined",
            counts[1], counts[2], counts[3], counts[0]
        ));
    }
    Ok(out)
}
