//! Error messages as strahl prints them: the chain of causes joined by ": ", each cause once.
//!
//! Many error types print their cause in their own message and also return it as their
//! `source()` (`io::Error` inside `image`'s and `toml`'s errors, for example), so the plain
//! alternate form of an `anyhow::Error` says "No such file or directory (os error 2): No such
//! file or directory (os error 2)". A cause whose text the message so far already holds is
//! left out.

/// `e` and its causes, outermost first, each cause once.
pub fn chain(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let m = cause.to_string();
        if m.is_empty() || text.contains(&m) {
            continue;
        }
        if !text.is_empty() {
            text.push_str(": ");
        }
        text.push_str(&m);
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;
    use anyhow::Context;

    /// An error that shows its source in its own message, as `image::ImageError::IoError` does.
    #[derive(Debug, thiserror::Error)]
    #[error("{0}")]
    struct Wraps(#[source] std::io::Error);

    #[test]
    fn each_cause_is_printed_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file or directory (os error 2)");
        let e = Err::<(), _>(Wraps(io)).context("cannot write out.png").unwrap_err();
        assert_eq!(
            format!("{e:#}"),
            "cannot write out.png: No such file or directory (os error 2): No such file or directory (os error 2)",
            "anyhow's own form repeats the cause"
        );
        assert_eq!(chain(&e), "cannot write out.png: No such file or directory (os error 2)");
        let plain = anyhow::anyhow!("inner").context("middle").context("outer");
        assert_eq!(chain(&plain), "outer: middle: inner");
    }
}
