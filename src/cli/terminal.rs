//! How the `tagk` command and the examples end: an error printed once with its causes, and a
//! closed pipe (`tagk … | head -1`) ending the program quietly instead of a panic.

use std::error::Error;
use std::process::ExitCode;

/// An error and its chain of causes as lines: the message, then each `caused by:` whose text
/// is not already shown.
///
/// Most messages quote their cause (`file: line 3, …` holds `line 3, …`); such a cause is
/// not printed again. The first line is prefixed with `program: `.
pub fn error_text(program: &str, err: &dyn Error) -> String {
    let mut shown = err.to_string();
    let mut text = format!("{program}: {shown}");
    let mut source = err.source();
    while let Some(cause) = source {
        let line = cause.to_string();
        if !shown.contains(line.trim()) {
            text.push_str("\n  caused by: ");
            text.push_str(&line);
            shown.push('\n');
            shown.push_str(&line);
        }
        source = cause.source();
    }
    text
}

/// Prints `err` on stderr as [`error_text`] does and returns the failure exit code.
pub fn report_error(program: &str, err: &dyn Error) -> ExitCode {
    eprintln!("{}", error_text(program, err));
    ExitCode::FAILURE
}

/// The end of a `main` returning a result: success, or the error printed once
/// ([`report_error`]) and a failure exit code.
pub fn exit_code<E: Into<Box<dyn Error>>>(program: &str, result: Result<(), E>) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => report_error(program, e.into().as_ref()),
    }
}

/// Whether a panic's message is `println!`'s on a closed pipe ("failed printing to stdout:
/// Broken pipe (os error 32)").
pub fn is_broken_pipe_panic(message: &str) -> bool {
    message.starts_with("failed printing to std")
        && (message.contains("Broken pipe") || message.contains("os error 32"))
}

/// Makes a closed stdout end the program quietly with exit code 0.
///
/// Rust ignores SIGPIPE, so `println!` to a reader that has gone (`tagk … | head -1`)
/// panics (exit code 101). After this call such a panic exits at once, printing nothing.
/// Every other panic is reported as before. Call it first in `main`.
pub fn end_quietly_on_broken_pipe() {
    let previous = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let payload = info.payload();
        let message = payload
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| payload.downcast_ref::<&str>().copied())
            .unwrap_or("");
        if is_broken_pipe_panic(message) {
            std::process::exit(0);
        }
        previous(info);
    }));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An error with a message of its own and an optional cause.
    #[derive(Debug)]
    struct Layer(String, Option<Box<Layer>>);

    impl std::fmt::Display for Layer {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str(&self.0)
        }
    }

    impl Error for Layer {
        fn source(&self) -> Option<&(dyn Error + 'static)> {
            self.1.as_deref().map(|e| e as &(dyn Error + 'static))
        }
    }

    fn chain(messages: &[&str]) -> Layer {
        let mut err: Option<Box<Layer>> = None;
        for m in messages.iter().rev() {
            err = Some(Box::new(Layer((*m).to_string(), err)));
        }
        *err.expect("one message")
    }

    #[test]
    fn a_quoted_cause_is_not_printed_again() {
        let e = chain(&[
            "bad.csv: line 5: `x` is not a number",
            "line 5: `x` is not a number",
        ]);
        assert_eq!(
            error_text("tagk", &e),
            "tagk: bad.csv: line 5: `x` is not a number"
        );
    }

    /// A middle layer that does not quote its cause: the cause is printed once, and the
    /// innermost cause, quoted by the middle one's cause, not at all.
    #[test]
    fn each_message_of_a_chain_appears_once() {
        let e = chain(&["cannot load the model", "m.toml: bad key", "bad key"]);
        let text = error_text("tagk", &e);
        assert_eq!(
            text,
            "tagk: cannot load the model\n  caused by: m.toml: bad key"
        );
        assert_eq!(text.matches("bad key").count(), 1);
    }

    #[test]
    fn a_new_cause_is_printed() {
        let e = chain(&[
            "reading the log failed",
            "No such file or directory (os error 2)",
        ]);
        assert_eq!(
            error_text("x", &e),
            "x: reading the log failed\n  caused by: No such file or directory (os error 2)"
        );
    }

    #[test]
    fn only_println_on_a_closed_pipe_counts_as_a_broken_pipe() {
        assert!(is_broken_pipe_panic(
            "failed printing to stdout: Broken pipe (os error 32)"
        ));
        assert!(!is_broken_pipe_panic("index out of bounds"));
        assert!(!is_broken_pipe_panic(
            "failed printing to stdout: No space left on device (os error 28)"
        ));
    }
}
