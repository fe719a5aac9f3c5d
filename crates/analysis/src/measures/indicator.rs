//! What a chaos indicator is to the rest of the program: a measure computed on one series (one
//! observable's samples on one section of a run: the strobe section by default) that gives one
//! number per run and a verdict for the classification ([`crate::measures::chaos::classify`]).
//!
//! An indicator is asked for by a table of the study named after its key (`[zero_one]`, with
//! `observable` and `section`: [`SeriesSpec`]), computed for the single run and for every sweep
//! value, and stored without code of its own in the storage layer: its number as the dataset
//! `/sweep/chaos/<row>` of a sweep (one value per row) and, for a single run, the attributes of
//! the group `/chaos/<key>`; summaries, the sweep table and the chaos-map figure read it by the
//! names its [`Row`] gives. The indicators are listed once, in
//! [`crate::measures::registry`].

use serde::Deserialize;

/// The table of a study that asks for an indicator: the series it reads.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SeriesSpec {
    /// Name of the observable the indicator runs on.
    pub observable: String,
    /// The section whose samples it uses: "strobe" (default) or a hyperplane section's name.
    #[serde(default = "strobe")]
    pub section: String,
}

fn strobe() -> String {
    "strobe".into()
}

/// An indicator a study asked for: which one and on which series.
#[derive(Clone)]
pub struct Asked {
    pub indicator: &'static dyn Indicator,
    pub series: SeriesSpec,
}

impl Asked {
    /// The indicator's key (its study table).
    pub fn key(&self) -> &'static str {
        self.indicator.key()
    }
}

impl std::fmt::Debug for Asked {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Asked")
            .field("key", &self.key())
            .field("series", &self.series)
            .finish()
    }
}

/// Two requests are the same when they name the same indicator (keys are unique in the
/// registry) on the same series.
impl PartialEq for Asked {
    fn eq(&self, other: &Asked) -> bool {
        self.key() == other.key() && self.series == other.series
    }
}

/// What an indicator says of a motion, for the classification.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// The series is constant to round-off: a period-1 strobe series, no number.
    Constant,
    /// Regular (periodic or quasi-periodic) motion.
    Regular,
    /// Chaotic motion.
    Chaotic,
    /// Between the thresholds: the indicator cannot tell.
    Unsure,
}

/// A number an indicator keeps about a single run, as an attribute of `/chaos/<key>`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Number {
    Real(f64),
    Flag(bool),
    Count(u64),
}

/// What an indicator read on one series.
#[derive(Debug, Clone, PartialEq)]
pub struct Reading {
    /// The indicator's key.
    pub key: &'static str,
    /// Its number (NaN when the series has none, e.g. a constant one).
    pub value: f64,
    pub verdict: Verdict,
    /// The attributes of a single run's group `/chaos/<key>`, its number first (named
    /// [`Row::name`]).
    pub attributes: Vec<(&'static str, Number)>,
}

/// How an indicator's number is named and shown.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    /// Dataset of a sweep (`/sweep/chaos/<name>`) and first attribute of a single run's group.
    pub name: &'static str,
    /// Unit (SI; "1" for a dimensionless number).
    pub unit: &'static str,
    /// The dataset's description.
    pub description: &'static str,
    /// Column header in the sweep table and axis label of the chaos map.
    pub column: &'static str,
    /// Digits after the point in the sweep table.
    pub digits: usize,
    /// Title of its panel in the chaos map.
    pub title: &'static str,
    /// The panel's vertical range, when the number has one.
    pub range: Option<(f64, f64)>,
}

/// A chaos indicator on one series (see the module overview).
pub trait Indicator: Sync {
    /// The study table that asks for it and its group in a single run's file: `zero_one`.
    fn key(&self) -> &'static str;
    /// Its name in sentences: "0-1 test".
    fn title(&self) -> &'static str;
    /// The fewest samples it runs on (a strobe section that keeps fewer is refused when the study
    /// is loaded).
    fn least_samples(&self) -> usize;
    /// How its number is named and shown.
    fn row(&self) -> Row;
    /// Computes it on `series` (an error is a sentence, reported with the study's field `key`).
    fn compute(&self, series: &[f64]) -> Result<Reading, String>;
    /// The summary line of a single run from its number (`{:<12}` aligned with the others).
    fn line(&self, value: f64) -> String;
}
