//! Limits on a YAML file before serde_yaml sees it (issue #46): its size and how deeply it
//! nests. The YAML parser builds every event of the document first, and a 200 kB file of
//! 100 000 nested `[` kept `check` busy for over a minute; no pipeline or study written by
//! hand needs more than a few levels (the shipped ones nest at most 6 deep).
//!
//! The depth is counted without parsing, conservatively: the block indentation levels open on
//! a line, plus the `- `, `? ` and `: ` indicators that start its content (each opens a
//! collection), plus the flow collections (`[`, `{`) open at each character outside quotes and
//! comments.

use std::io::Read;
use std::path::Path;

/// The largest YAML file read (a pipeline or study is a few kB).
pub const MAX_YAML_BYTES: u64 = 4 << 20;
/// The deepest nesting of collections accepted.
pub const MAX_YAML_DEPTH: usize = 64;

/// The text of the YAML file at `path`, refused (a message for the caller's error) when it
/// cannot be read, is larger than `MAX_YAML_BYTES` or nests deeper than `MAX_YAML_DEPTH`.
/// `what` names the file's kind: "pipeline", "study".
pub fn read_yaml(path: &Path, what: &str) -> Result<String, String> {
    let cannot = |e: std::io::Error| format!("cannot read the {what} file: {e}");
    let file = std::fs::File::open(path).map_err(cannot)?;
    if file.metadata().is_ok_and(|m| m.len() > MAX_YAML_BYTES) {
        return Err(too_large(what));
    }
    let mut text = String::new();
    file.take(MAX_YAML_BYTES + 1)
        .read_to_string(&mut text)
        .map_err(cannot)?;
    check_yaml(&text, what)?;
    Ok(text)
}

/// `text` within `MAX_YAML_BYTES` and `MAX_YAML_DEPTH`, else a message naming the limit (and
/// the line where the nesting passes it).
pub fn check_yaml(text: &str, what: &str) -> Result<(), String> {
    if text.len() as u64 > MAX_YAML_BYTES {
        return Err(too_large(what));
    }
    if let Some((line, depth)) = too_deep(text, MAX_YAML_DEPTH) {
        return Err(format!(
            "line {line}: the YAML nests {depth} collections deep, beyond the limit of {MAX_YAML_DEPTH} (a {what} needs a few levels); refused before parsing"
        ));
    }
    Ok(())
}

fn too_large(what: &str) -> String {
    format!(
        "larger than {} MiB, the limit of a {what} file (they are a few kB): is it the right file?",
        MAX_YAML_BYTES >> 20
    )
}

/// The first line (1-based) where the nesting exceeds `limit`, and the depth reached there.
fn too_deep(text: &str, limit: usize) -> Option<(usize, usize)> {
    let mut indents: Vec<usize> = Vec::new();
    let mut flow = 0usize;
    for (i, line) in text.lines().enumerate() {
        let content = line.trim_start_matches(' ');
        let indent = line.len() - content.len();
        let mut depth = 0;
        let mut rest = content;
        if flow == 0 && !content.is_empty() && !content.starts_with('#') {
            while indents.last().is_some_and(|&top| top > indent) {
                indents.pop();
            }
            if indents.last().is_none_or(|&top| top < indent) {
                indents.push(indent);
            }
            depth = indents.len();
            // Indicators that open a collection on the same line: `- - x`, `? a`, `: b`.
            loop {
                let opened = ["- ", "? ", ": "].iter().find_map(|p| rest.strip_prefix(p));
                match opened {
                    Some(tail) => {
                        depth += 1;
                        rest = tail.trim_start_matches(' ');
                    }
                    None => break,
                }
            }
        }
        if depth > limit {
            return Some((i + 1, depth));
        }
        let mut quote: Option<char> = None;
        let mut previous = ' ';
        let mut chars = rest.chars().peekable();
        while let Some(c) = chars.next() {
            match quote {
                Some('\'') if c == '\'' => {
                    if chars.peek() == Some(&'\'') {
                        chars.next();
                    } else {
                        quote = None;
                    }
                }
                Some('"') if c == '\\' => {
                    chars.next();
                }
                Some(q) if c == q => quote = None,
                Some(_) => {}
                None => match c {
                    '\'' | '"' => quote = Some(c),
                    '#' if previous == ' ' || previous == '\t' => break,
                    '[' | '{' => {
                        flow += 1;
                        if depth + flow > limit {
                            return Some((i + 1, depth + flow));
                        }
                    }
                    ']' | '}' => flow = flow.saturating_sub(1),
                    _ => {}
                },
            }
            previous = c;
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shallow_yaml_passes_and_deep_flow_or_block_nesting_is_caught_at_its_line() {
        let ok = "name: a\ngeometry:\n  file: x.geo\n  parameters: {gap: 1.0e-7}\nboundaries:\n  loads:\n    - group: tip\n      harmonics:\n        - {k: 1, cos: [0.0, 1.0]}\n# [[[[ in a comment\nname2: '[[[['\n";
        assert_eq!(too_deep(ok, 8), None);
        let flow = format!("a: 1\nb: {}{}\n", "[".repeat(70), "]".repeat(70));
        assert_eq!(too_deep(&flow, 64), Some((2, 65)));
        let block = format!("{}x\n", "- ".repeat(100));
        assert_eq!(too_deep(&block, 64), Some((1, 101)));
        let mut indented = String::new();
        for d in 0..70 {
            indented.push_str(&format!("{}k{d}:\n", " ".repeat(d)));
        }
        assert_eq!(too_deep(&indented, 64).map(|(l, _)| l), Some(65));
    }
}
