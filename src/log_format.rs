//! Log lines that a client cannot forge: every field value is written with
//! its control characters escaped.
//!
//! Client-supplied text (a query value, an unknown parameter name, a part
//! name) reaches the log through error details, span fields and messages.
//! A raw line feed in it would end the event's line and let the rest pose as
//! a new event with its own timestamp and level. Escaping at the formatter
//! ([`escaping_fields`]) covers every field of every event and span at one
//! place, whatever way (`%`, `?`, message) a value was recorded:
//! `\n`, `\r`, `\t` become `\\n`, `\\r`, `\\t`; other C0 and C1 controls,
//! DEL and the Unicode line and paragraph separators become `\u{..}`.

use std::borrow::Cow;
use std::fmt::{self, Write as _};

use tracing::field::Field;
use tracing_subscriber::field::MakeExt;
use tracing_subscriber::fmt::FormatFields;
use tracing_subscriber::fmt::format::{Writer, debug_fn};

/// True for characters that may not appear raw in a log line.
fn needs_escape(c: char) -> bool {
    c.is_control() || matches!(c, '\u{2028}' | '\u{2029}')
}

/// `text` with control characters escaped (borrowed when there are none).
pub fn log_safe(text: &str) -> Cow<'_, str> {
    if !text.chars().any(needs_escape) {
        return Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len() + 16);
    for c in text.chars() {
        match c {
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c if needs_escape(c) => {
                let _ = write!(out, "\\u{{{:x}}}", u32::from(c));
            }
            c => out.push(c),
        }
    }
    Cow::Owned(out)
}

/// Writes one field as `name=value` (the message as its bare text), escaped.
fn write_escaped_field(w: &mut Writer<'_>, field: &Field, value: &dyn fmt::Debug) -> fmt::Result {
    let text = format!("{value:?}");
    let text = log_safe(&text);
    if field.name() == "message" { write!(w, "{text}") } else { write!(w, "{}={text}", field.name()) }
}

/// The field formatter of the service's log: like tracing's default
/// (space-separated `name=value`), with every value passed through
/// [`log_safe`], so one event is always one line.
pub fn escaping_fields() -> impl for<'w> FormatFields<'w> + Send + Sync + 'static {
    debug_fn(write_escaped_field).delimited(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn control_characters_are_escaped_and_plain_text_is_borrowed() {
        assert!(matches!(log_safe("cursor `abc` is bad"), Cow::Borrowed(_)));
        assert_eq!(log_safe("1\n2026-01-01T00:00:00Z ERROR x"), "1\\n2026-01-01T00:00:00Z ERROR x");
        assert_eq!(log_safe("a\r\tb"), "a\\r\\tb");
        assert_eq!(log_safe("\u{1b}[31m\u{7f}\u{85}\u{2028}é"), "\\u{1b}[31m\\u{7f}\\u{85}\\u{2028}é");
    }

    #[test]
    fn events_with_forged_lines_stay_on_one_line() {
        use std::sync::{Arc, Mutex};
        #[derive(Clone, Default)]
        struct Buf(Arc<Mutex<Vec<u8>>>);
        impl std::io::Write for Buf {
            fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
                self.0.lock().unwrap().extend_from_slice(b);
                Ok(b.len())
            }
            fn flush(&mut self) -> std::io::Result<()> {
                Ok(())
            }
        }
        let buf = Buf::default();
        let writer = buf.clone();
        let subscriber = tracing_subscriber::fmt()
            .fmt_fields(escaping_fields())
            .with_writer(move || writer.clone())
            .with_ansi(false)
            .finish();
        let evil = "x\n2026-01-01T00:00:00.000000Z ERROR meshatlas: FORGED";
        tracing::subscriber::with_default(subscriber, || {
            let span = tracing::info_span!("request", path = %evil);
            let _g = span.enter();
            tracing::info!(detail = %evil, debug = ?evil, "rejected {evil}");
        });
        let out = String::from_utf8(buf.0.lock().unwrap().clone()).unwrap();
        assert_eq!(out.lines().count(), 1, "{out}");
        assert_eq!(out.matches("x\\n2026-01-01").count(), 4, "{out}");
        assert!(out.contains("detail=x\\n2026") && out.contains("path=x\\n2026"), "{out}");
    }
}
