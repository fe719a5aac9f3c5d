//! Every chaos indicator the program knows ([`crate::measures::indicator::Indicator`]), listed
//! once: adding one is its own file, its entry here, and its documentation.
//!
//! `with_indicator_tables` appends a field per indicator to the analysis study's spec (its
//! table, `[<key>]`, optional), so that the study file is read by the same typed parser that
//! refuses unknown fields and names them with their line; [`INDICATORS`] lists them for
//! everything else (checks, computation, storage, summaries, tables, figures).

use crate::measures::indicator::Indicator;

/// The indicators, in the order their numbers are stored and shown.
pub static INDICATORS: &[&dyn Indicator] = &[&crate::measures::zero_one::ZeroOneTest];

/// The indicator of key `key`.
pub fn find(key: &str) -> Option<&'static dyn Indicator> {
    INDICATORS.iter().copied().find(|i| i.key() == key)
}

/// Appends to a spec struct one optional field per indicator, named after its key and holding
/// its table ([`crate::measures::indicator::SeriesSpec`]), and a method `asked` listing the
/// tables given, in the order of [`INDICATORS`].
macro_rules! with_indicator_tables {
    ($(#[$meta:meta])* pub struct $name:ident { $($body:tt)* }) => {
        $(#[$meta])*
        pub struct $name {
            $($body)*
            /// `[zero_one]`: the 0-1 test for chaos ([`crate::measures::zero_one`]).
            #[serde(default)]
            pub zero_one: Option<crate::measures::indicator::SeriesSpec>,
        }

        impl $name {
            /// The indicators the study asks for, in the order of
            /// [`crate::measures::registry::INDICATORS`].
            pub fn asked(&self) -> Vec<crate::measures::indicator::Asked> {
                let tables = [("zero_one", &self.zero_one)];
                crate::measures::registry::INDICATORS
                    .iter()
                    .filter_map(|i| {
                        let (_, table) = tables.iter().find(|(k, _)| *k == i.key())?;
                        table.as_ref().map(|s| crate::measures::indicator::Asked {
                            indicator: *i,
                            series: s.clone(),
                        })
                    })
                    .collect()
            }
        }
    };
}
pub(crate) use with_indicator_tables;

#[cfg(test)]
mod tests {
    use std::collections::BTreeSet;
    use std::path::Path;

    use super::*;
    use crate::study::analysis::spec::AnalysisStudy;

    /// What a new indicator must satisfy to be stored, shown and asked for without code of its
    /// own elsewhere: a key of its own that a study table reaches, a row name that no dataset of
    /// `/sweep/chaos` already has, and a number with a unit.
    #[test]
    fn every_registered_indicator_is_reachable_and_stored_apart() {
        let mut keys = BTreeSet::new();
        // The Lyapunov spectrum's and the classification's datasets in /sweep/chaos.
        let mut rows: BTreeSet<&str> = [
            "class",
            "exponents",
            "stderr",
            "map_exponents",
            "two_trajectory",
        ]
        .into();
        for i in INDICATORS {
            assert!(keys.insert(i.key()), "two indicators named {}", i.key());
            let row = i.row();
            assert!(rows.insert(row.name), "{}: row {} taken", i.key(), row.name);
            assert!(!row.unit.is_empty() && !row.column.is_empty() && !row.title.is_empty());
            assert!(find(i.key()).is_some_and(|f| f.key() == i.key()));
            // Its table in a study file is read into the spec, and only its own.
            let text = format!(
                "[study]\nname = \"s\"\nsystem = {{ kind = \"duffing\" }}\n\
                 [analysis]\nperiods = 2\ntransient = 1\n\
                 [{}]\nobservable = \"x\"\n",
                i.key()
            );
            let spec = AnalysisStudy::parse_spec(&text, Path::new("s.toml")).unwrap();
            let asked = spec.asked();
            assert_eq!(asked.len(), 1, "{}", i.key());
            assert_eq!(asked[0].key(), i.key());
            assert_eq!(asked[0].series.observable, "x");
            assert_eq!(asked[0].series.section, "strobe");
            // A reading names its indicator and leads its attributes with its number.
            let r = i.compute(&vec![0.25; i.least_samples()]).unwrap();
            assert_eq!(r.key, i.key());
            assert_eq!(r.attributes.first().map(|a| a.0), Some(row.name));
        }
        assert!(find("no such indicator").is_none());
    }
}
