//! What a `.geo` lets `-setnumber` change: the names in its `DefineConstant[...]` blocks. A
//! plain assignment `name = value;` in the file runs after `-setnumber` and overrides it, and a
//! name the file never mentions does nothing; both would silently ignore a pipeline's
//! `geometry.parameters` entry, so both are refused.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use crate::{Error, Result};

/// The `.geo`'s parameters: names defined in `DefineConstant` and names plainly assigned.
#[derive(Debug, Default, PartialEq)]
pub struct GeoNames {
    pub constants: BTreeSet<String>,
    pub assigned: BTreeSet<String>,
}

/// Strip `//` and `/* */` comments.
fn strip_comments(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix("//") {
            rest = r.find('\n').map_or("", |i| &r[i..]);
        } else if let Some(r) = rest.strip_prefix("/*") {
            rest = r.find("*/").map_or("", |i| &r[i + 2..]);
        } else {
            let c = rest.chars().next().unwrap_or(' ');
            out.push(c);
            rest = &rest[c.len_utf8()..];
        }
    }
    out
}

fn identifier_before_equals(s: &str) -> Option<&str> {
    let (name, _) = s.split_once('=')?;
    let name = name.trim();
    let ok = !name.is_empty()
        && name
            .chars()
            .next()
            .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    ok.then_some(name)
}

/// Read the names a `.geo` text defines.
pub fn geo_names(text: &str) -> GeoNames {
    let text = strip_comments(text);
    let mut names = GeoNames::default();
    let mut rest = text.as_str();
    let mut outside = String::new();
    while let Some(i) = rest.find("DefineConstant") {
        outside.push_str(&rest[..i]);
        let after = &rest[i..];
        let (Some(open), Some(close)) = (after.find('['), after.find(']')) else {
            break;
        };
        // Entries `name = {value, options}` or `name = value`, separated by commas at depth 0.
        let body = &after[open + 1..close];
        let mut depth = 0;
        let mut start = 0;
        for (j, c) in body.char_indices().chain([(body.len(), ',')]) {
            match c {
                '{' | '(' => depth += 1,
                '}' | ')' => depth -= 1,
                ',' if depth == 0 => {
                    if let Some(name) = identifier_before_equals(&body[start..j]) {
                        names.constants.insert(name.to_string());
                    }
                    start = j + 1;
                }
                _ => {}
            }
        }
        rest = &after[close + 1..];
    }
    outside.push_str(rest);
    for statement in outside.split(';') {
        if let Some(name) = identifier_before_equals(statement) {
            names.assigned.insert(name.to_string());
        }
    }
    names
}

/// Refuse `geometry.parameters` entries that the `.geo` would ignore, with a did-you-mean.
pub fn check_parameters(geo: &Path, given: &BTreeMap<String, f64>) -> Result<()> {
    if given.is_empty() {
        return Ok(());
    }
    let text = std::fs::read_to_string(geo)
        .map_err(|e| Error::Input(format!("geometry.file: cannot read {}: {e}", geo.display())))?;
    let names = geo_names(&text);
    for name in given.keys() {
        if names.constants.contains(name) {
            continue;
        }
        if names.assigned.contains(name) {
            return Err(Error::Input(format!(
                "geometry.parameters.{name}: {} assigns `{name}` plainly, which overrides the \
                 value gmsh is given: declare it in a DefineConstant[ {name} = {{value, Name \
                 \"Parameters/{name}\"}} ]; block to make it a parameter",
                geo.display()
            )));
        }
        let best = names
            .constants
            .iter()
            .map(|c| (strsim::jaro_winkler(name, c), c))
            .filter(|(s, _)| *s > 0.7)
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, c)| format!("; did you mean `{c}`?"))
            .unwrap_or_default();
        let known: Vec<&str> = names.constants.iter().map(String::as_str).collect();
        return Err(Error::Input(format!(
            "geometry.parameters.{name}: {} has no parameter `{name}` (its parameters: {}){best}",
            geo.display(),
            if known.is_empty() {
                "none".to_string()
            } else {
                known.join(", ")
            }
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn define_constants_and_plain_assignments_are_told_apart() {
        let text = "// W = 3;\nDefineConstant[\n  W = {0.2, Name \"Parameters/W\"},\n  lc = {0.01, Min 1, Max 2},\n  n = 3\n];\n/* h = 2; */ rc = Sqrt(W^2 + 1);\nPoint(1) = {0, 0, 0, lc};\n";
        let names = geo_names(text);
        let set = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<BTreeSet<_>>();
        assert_eq!(names.constants, set(&["W", "lc", "n"]));
        assert_eq!(names.assigned, set(&["rc"]));
    }
}
