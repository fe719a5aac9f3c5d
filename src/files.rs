//! Commands over written files: `jointplay report` (a study's table), `jointplay plot` (an
//! analysis or work-precision file's figures), `jointplay compare` (one quantity of several runs)
//! and `jointplay merge` (a sweep's shards into its study file).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use jointplay_analysis::figures::plot::{Format, figure};
use jointplay_analysis::figures::{overlay, redraw, redraw_with};
use jointplay_analysis::storage::inputs::{Input, Output};
use jointplay_analysis::study::report::{self, markdown};
use jointplay_analysis::study::shards::merge;

use crate::VERSION;

pub fn report_cmd(file: &Path, out: Option<&Path>) -> Result<()> {
    // The table is a comparison study's: other files get the command that fits them.
    let toml = file.extension().is_some_and(|e| e == "toml");
    let other = match Output::read(file) {
        _ if toml => Some(match Input::read(file) {
            Ok((Input::Comparison, _)) => format!(
                "a comparison study's TOML file: `jointplay report` reads the HDF5 file its run \
                 wrote (`jointplay run {}` writes DIR/<study>.h5, and its table DIR/<study>.md)",
                file.display()
            ),
            _ => "a TOML file: `jointplay report` reads the HDF5 file of a comparison study's \
                  run (DIR/<study>.h5)"
                .to_string(),
        }),
        Ok(Output::Comparison) => None,
        Ok(Output::Analysis) => match jointplay_analysis::storage::table::of_file(file)? {
            // A sweep's table: one row per value.
            Some(t) => {
                return emit(&t.markdown, out);
            }
            None => Some(
                "a single analysis run's file: `jointplay report` makes the table of a sweep or a \
                 comparison study; `jointplay plot FILE` redraws this file's figures, and its \
                 datasets are read as the book's HDF5 reference describes"
                    .to_string(),
            ),
        },
        Ok(Output::Precision) => Some(
            "a work-precision file: its table is DIR/<name>.md, written beside it by \
             `jointplay precision`; `jointplay plot FILE` redraws its figure"
                .to_string(),
        ),
        Ok(Output::Run) => Some(
            "a scene's run file: `jointplay report` makes a comparison study's table; \
             `jointplay compare` overlays a recorded quantity of several runs"
                .to_string(),
        ),
        Err(e) => return Err(e.into()),
    };
    if let Some(why) = other {
        anyhow::bail!("{}: {why}", file.display());
    }
    emit(&markdown(&report::compute(file)?), out)
}

/// A table to `out` (whole or not at all) or to standard output.
fn emit(md: &str, out: Option<&Path>) -> Result<()> {
    match out {
        Some(p) => {
            jointplay_analysis::storage::durable::write_new(p, md.as_bytes())?;
            println!("wrote        {}", p.display());
        }
        None => print!("{md}"),
    }
    Ok(())
}

pub fn plot_cmd(
    file: &Path,
    format: &str,
    out: Option<&Path>,
    figures: Option<&Path>,
) -> Result<()> {
    let dir = out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| file.parent().unwrap_or(Path::new(".")).to_path_buf());
    let formats =
        Format::list(format).with_context(|| format!("--format {format}: use png, svg or both"))?;
    for f in redraw_with(file, &dir, &formats, figures)? {
        println!("wrote        {}", f.display());
    }
    Ok(())
}

pub fn compare(
    files: &[PathBuf],
    dataset: &str,
    component: usize,
    out: &Path,
    title: Option<String>,
) -> Result<()> {
    let panel = overlay(files, dataset, component, title)?;
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    for fmt in [Format::Png, Format::Svg] {
        println!(
            "wrote        {}",
            figure(out, fmt, std::slice::from_ref(&panel), 1)?.display()
        );
    }
    Ok(())
}

/// Merges shard files into the study file, prints what the values cost and draws the figures.
pub fn merge_cmd(files: &[PathBuf], out: &Path, partial: bool, plots: bool) -> Result<()> {
    let m = merge(files, out, VERSION, partial)?;
    println!(
        "merged       {} shard files of {} into {} values",
        files.len(),
        m.shards,
        m.jobs
    );
    let w = &m.value_walls;
    if !w.is_empty() {
        let total: f64 = w.iter().sum();
        let max = w.iter().fold(0.0f64, |a, &b| a.max(b));
        println!(
            "cost         {total:.3} s of computing over {} values: {:.4} s per value on \
             average, {max:.4} s at most",
            w.len(),
            total / w.len() as f64
        );
    }
    if let (Some(lo), Some(hi)) = (
        m.shard_walls.iter().min_by(|a, b| a.1.total_cmp(&b.1)),
        m.shard_walls.iter().max_by(|a, b| a.1.total_cmp(&b.1)),
    ) {
        println!(
            "shards       {:.3} s (shard {}) to {:.3} s (shard {}) of wall time each",
            lo.1, lo.0, hi.1, hi.0
        );
    }
    println!("wrote        {}", m.file.display());
    for t in &m.tables {
        println!("wrote        {}", t.display());
    }
    if plots {
        let dir = out
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        for f in redraw(&m.file, dir, &[Format::Png, Format::Svg])? {
            println!("wrote        {}", f.display());
        }
    }
    if !m.not_done.is_empty() {
        println!(
            "incomplete   {} values written as not done: finish with `jointplay run STUDY --out \
             DIR --resume`",
            m.not_done.len()
        );
    }
    Ok(())
}

/// `jointplay export`: a run's samples as CSV or MAT.
pub fn export(
    file: &Path,
    format: crate::cli::ExportFormat,
    case: Option<&str>,
    datasets: &[String],
    out: &Path,
) -> Result<()> {
    use jointplay_analysis::storage::export::{self, Format};
    not_toml(file, "export")?;
    let format = match format {
        crate::cli::ExportFormat::Csv => Format::Csv,
        crate::cli::ExportFormat::Mat => Format::Mat,
    };
    let path = export::export(file, case, datasets, format, out)?;
    println!("wrote        {}", path.display());
    Ok(())
}

/// Which motion of a file `jointplay animate` draws, as its options give it.
pub struct Picked<'a> {
    pub case: Option<&'a str>,
    pub value: Option<f64>,
    pub periods: f64,
    pub orbit: Option<&'a str>,
}

/// `jointplay animate`: the page (and with `glb` the glTF file) of a run, a study's case, a
/// sweep value or a periodic orbit.
pub fn animate(
    file: &Path,
    picked: Picked,
    out: &Path,
    frames: usize,
    speed: Option<f64>,
    glb: bool,
) -> Result<()> {
    use jointplay_analysis::figures::animate::{Options, Pick, write_page};
    not_toml(file, "animate")?;
    if frames < 2 {
        anyhow::bail!("--frames: at least 2, got {frames}");
    }
    if let Some(s) = speed.filter(|s| !(s.is_finite() && *s > 0.0)) {
        anyhow::bail!("--speed: a positive number of simulated seconds per second, got {s}");
    }
    let pick = match (picked.value, picked.orbit) {
        (Some(value), _) => {
            if !(picked.periods.is_finite() && picked.periods > 0.0) {
                anyhow::bail!("--periods: a positive number, got {}", picked.periods);
            }
            Pick::Value {
                value,
                periods: picked.periods,
            }
        }
        (None, Some(o)) => {
            let parsed = o
                .split_once(':')
                .and_then(|(b, p)| Some((b.trim().parse().ok()?, p.trim().parse().ok()?)));
            let Some((branch, point)) = parsed else {
                anyhow::bail!("--orbit: BRANCH:POINT, two indices (e.g. 0:3), got '{o}'");
            };
            Pick::Orbit { branch, point }
        }
        (None, None) => Pick::Run { case: picked.case },
    };
    let options = Options { frames, speed };
    let (page, motion) = write_page(file, pick, out, &options)?;
    let size = std::fs::metadata(&page).map(|m| m.len()).unwrap_or(0);
    println!(
        "wrote        {} ({} frames of {} samples, {} of them for contacts; {:.1} MB)",
        page.display(),
        motion.time.len(),
        motion.samples,
        motion.impact_frames,
        size as f64 / 1e6
    );
    if !motion.missing.is_empty() {
        println!(
            "not drawn    {} (not recorded: add them to [output] bodies)",
            motion.missing.join(", ")
        );
    }
    if glb {
        let path = jointplay_analysis::figures::gltf::write(&motion, file, pick, out)?;
        println!("wrote        {}", path.display());
    }
    Ok(())
}

/// Refuses a TOML file given to `command`, which reads the HDF5 file a run wrote.
fn not_toml(file: &Path, command: &str) -> Result<()> {
    if file.extension().is_some_and(|e| e == "toml") {
        anyhow::bail!(
            "{}: a TOML file; `jointplay {command}` reads the HDF5 file a run wrote (`jointplay run {}` writes DIR/<name>.h5)",
            file.display(),
            file.display()
        );
    }
    Ok(())
}
