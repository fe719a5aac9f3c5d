//! The solver crate's one error type.
//!
//! Every variant carries what a user needs to find the cause: the scene file, the field path inside
//! it (`joints[3].axis_a`), the joint or drive name, or the simulated time at which the numerics
//! failed. Nothing in this crate panics on user input.

use std::path::PathBuf;

/// Errors raised while reading, validating, compiling or simulating a scene.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The scene file could not be read.
    #[error("{file}: cannot read")]
    Io {
        file: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The scene is not valid TOML or does not match the scene schema.
    #[error("{file}: {message}")]
    Parse { file: PathBuf, message: String },
    /// A field has a value the solver cannot accept.
    #[error("{file}: {field}: {message}")]
    Invalid {
        file: PathBuf,
        field: String,
        message: String,
    },
    /// The initial configuration could not be brought onto the constraints.
    #[error("{file}: initial assembly failed at t = {time} s: {message}")]
    Assembly {
        file: PathBuf,
        time: f64,
        message: String,
    },
    /// The integration produced a non-finite state or could not continue.
    #[error("integration stopped at t = {time} s: {message}")]
    Diverged { time: f64, message: String },
    /// A `disable` entry names no effect ([`crate::disable`]); `known` lists the effects.
    #[error("unknown effect '{name}'; known: {known}")]
    UnknownEffect { name: String, known: String },
    /// A `disable` entry scopes to one joint an effect of the whole scene; `per_joint` lists the
    /// effects a joint has.
    #[error("'{name}' is not a joint effect; per joint: {per_joint}")]
    NotJointEffect { name: String, per_joint: String },
    /// A `disable` entry names a joint the scene does not have.
    #[error("no joint '{joint}'")]
    NoJoint { joint: String },
    /// A `disable` entry would remove what the scene does not have (`what` says so).
    #[error("nothing to disable: {what}")]
    NothingToDisable { what: String },
    /// A program's command line is not what it takes: its usage.
    #[error("{usage}")]
    Usage { usage: &'static str },
    /// A command-line argument that must be a number is not.
    #[error("{argument} '{value}' is not a number")]
    NotANumber { argument: String, value: String },
    /// A command-line number that must be positive is not.
    #[error("{argument} {value} must be positive")]
    NotPositive { argument: String, value: f64 },
    /// A method family named where an integrator with error control is needed.
    #[error("'{family}' is not an adaptive integrator")]
    NotAdaptive { family: String },
}

/// Result alias of the solver crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// The most characters of input (a name, a value, a line of the file) an error message echoes.
pub const ECHO_LIMIT: usize = 200;

/// The longest line of a message the program prints before [`clip_lines`] cuts it.
pub const MESSAGE_LIMIT: usize = 10 * ECHO_LIMIT;

/// `text` as an error message echoes it: at most [`ECHO_LIMIT`] characters, then
/// "... (N more characters)", so that a huge value in a file does not flood the message.
pub fn clip(text: &str) -> std::borrow::Cow<'_, str> {
    match text.char_indices().nth(ECHO_LIMIT) {
        None => text.into(),
        Some((cut, _)) => {
            let more = text[cut..].chars().count();
            format!("{}... ({more} more characters)", &text[..cut]).into()
        }
    }
}

/// Every line of a message longer than `longest` characters clipped: such a line holds echoed
/// input (the parser's copy of the offending line, a value quoted in full). It keeps its first
/// and last [`ECHO_LIMIT`] characters around "... (N more characters) ...", so that what the
/// program says after the echo (the file a path ends with, "expected f64") survives. The parser's
/// messages are clipped at three times [`ECHO_LIMIT`], where they are made; the program's and
/// the Python module's messages at [`MESSAGE_LIMIT`], a net for any other echo.
pub fn clip_lines(message: &str, longest: usize) -> std::borrow::Cow<'_, str> {
    let longest = longest.max(2 * ECHO_LIMIT);
    let long = |l: &str| l.chars().count() > longest;
    if !message.split('\n').any(long) {
        return message.into();
    }
    let lines: Vec<String> = message
        .split('\n')
        .map(|l| {
            if !long(l) {
                return l.to_string();
            }
            let chars: Vec<char> = l.chars().collect();
            let head: String = chars[..ECHO_LIMIT].iter().collect();
            let tail: String = chars[chars.len() - ECHO_LIMIT..].iter().collect();
            let more = chars.len() - 2 * ECHO_LIMIT;
            format!("{head}... ({more} more characters) ...{tail}")
        })
        .collect();
    lines.join("\n").into()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Error messages echoed up to 10 MB of input (a huge string in a TOML field).
    #[test]
    fn error_messages_echo_at_most_200_characters_of_input() {
        let huge = "x".repeat(10_000_000);
        let clipped = clip(&huge);
        assert_eq!(
            clipped,
            format!("{}... (9999800 more characters)", "x".repeat(200))
        );
        assert_eq!(clip("short"), "short");
        let message = format!("head\n1 | name = \"{huge}\"\ntail");
        let clipped = clip_lines(&message, 3 * ECHO_LIMIT);
        assert_eq!(clipped.lines().count(), 3);
        assert!(clipped.len() < 500, "{clipped}");
        assert!(
            clipped.contains("... (9999613 more characters) ..."),
            "{clipped}"
        );
        assert!(clipped.contains("xx\"\ntail"), "{clipped}");
        let own = "y".repeat(500);
        assert_eq!(clip_lines(&own, 3 * ECHO_LIMIT), own);
    }
}
