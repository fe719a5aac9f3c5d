//! What every pass shares: the compilation context [`Ctx`] (the file, for errors that name it
//! and the field path, and the warnings so far) and small helpers for fields. A leaf: the passes
//! import it and it imports none of them.

use std::path::Path;

use nalgebra::Vector3;

use crate::error::{Error, Result};

/// The file being compiled, and the warnings found so far.
pub(crate) struct Ctx<'a> {
    file: &'a Path,
    warnings: std::cell::RefCell<Vec<String>>,
}

impl<'a> Ctx<'a> {
    pub(crate) fn new(file: &'a Path) -> Self {
        Ctx {
            file,
            warnings: Default::default(),
        }
    }

    /// The file being compiled.
    pub(crate) fn file(&self) -> &Path {
        self.file
    }

    /// Records a warning about `field`.
    pub(crate) fn warn(&self, field: impl std::fmt::Display, message: impl std::fmt::Display) {
        self.warnings
            .borrow_mut()
            .push(format!("{}: {field}: {message}", self.file.display()));
    }

    /// An error about `field`.
    pub(crate) fn err(&self, field: impl Into<String>, message: impl Into<String>) -> Error {
        Error::Invalid {
            file: self.file.to_path_buf(),
            field: field.into(),
            message: message.into(),
        }
    }

    /// The warnings recorded, in order.
    pub(crate) fn into_warnings(self) -> Vec<String> {
        self.warnings.into_inner()
    }
}

pub(crate) fn v3(a: [f64; 3]) -> Vector3<f64> {
    Vector3::new(a[0], a[1], a[2])
}

/// `v` when it is given and positive; `what` describes it when it is missing.
pub(crate) fn positive(v: Option<f64>, field: String, what: &str, cx: &Ctx) -> Result<f64> {
    match v {
        None => Err(cx.err(field, format!("missing: {what}"))),
        Some(x) if x > 0.0 => Ok(x),
        Some(x) => Err(cx.err(field, format!("must be positive, got {x}"))),
    }
}

/// Declared names for an error message ("none" for none).
pub(crate) fn list<'a>(it: impl Iterator<Item = &'a String>) -> String {
    let v: Vec<&str> = it.map(|s| s.as_str()).collect();
    if v.is_empty() {
        "none".into()
    } else {
        v.join(", ")
    }
}
