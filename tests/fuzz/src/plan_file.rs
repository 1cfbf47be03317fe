//! The ground's plan files (`ground_ops::plan::parse`: TOML, then every check across steps
//! and robots), which an operator may be handed from anywhere.
//!
//! The input is the file's text (inputs that are not UTF-8 are skipped: the loader refuses
//! them before parsing). Invariants: nothing panics; a refusal names at least one error,
//! each with a span inside the text (the CLI prints the line it points at).

pub fn run(data: &[u8]) {
    let Ok(src) = std::str::from_utf8(data) else {
        return;
    };
    if let Err(errors) = ground_ops::plan::parse(src) {
        assert!(!errors.is_empty(), "refused without an error");
        for e in &errors {
            assert!(
                e.span.start <= e.span.end && e.span.end <= src.len(),
                "span {:?} outside the {} bytes of the plan: {}",
                e.span,
                src.len(),
                e.message
            );
        }
    }
}
