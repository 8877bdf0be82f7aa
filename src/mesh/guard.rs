//! A `.geo` is data, not code: before gmsh reads one, its statements that would run a program
//! or touch files outside the meshing are refused, naming file:line.
//!
//! gmsh's language can run programs (`SystemCall`, `NonBlockingSystemCall`, `Shell`,
//! `OnelabRun`), write, delete, rename or create files (`Printf(…) > "f"` and `>> "f"`,
//! `Print "f"`, `Save "f"`, `Delete "f"`/`DeleteFile "f"`, `RenameFile`, `CreateDir`) and read
//! others (`Include`, `Merge`, `MergeWithBoundingBox`, `ShapeFromFile`). The scan reads the
//! file as tokens (identifiers, string literals, punctuation) with `//` and `/* */` comments
//! dropped, so a comment or a string that mentions these words is no statement; an identifier
//! after `.` is an option (`Print.Width`), not a command. `Include`/`Merge` must name a
//! literal path inside the folder tree of the geometry the pipeline names; included `.geo`
//! files are scanned in turn, at most `MAX_DEPTH` deep and `MAX_FILES` in all.
//!
//! `--trust-geometry` (the `MeshRequest`'s `trusted`) skips the scan, for a geometry one
//! wrote oneself.

use std::path::{Component, Path, PathBuf};

use crate::{Error, Result};

/// Statements that run a program.
const RUNS: [&str; 4] = ["SystemCall", "NonBlockingSystemCall", "Shell", "OnelabRun"];
/// Statements that write, delete, rename or create files.
const WRITES: [&str; 6] = [
    "Print",
    "Save",
    "DeleteFile",
    "RenameFile",
    "CreateDir",
    "Delete",
];
/// Statements that read another file.
const READS: [&str; 4] = ["Include", "Merge", "MergeWithBoundingBox", "ShapeFromFile"];
/// How deep `Include`s nest, and how many files one scan reads.
pub const MAX_DEPTH: usize = 8;
pub const MAX_FILES: usize = 64;

#[derive(Clone, Debug, PartialEq)]
enum Token {
    Ident(String),
    Text(String),
    Punct(char),
    Other,
}

/// The tokens of a `.geo` text with their 1-based lines; comments dropped.
fn tokens(text: &str) -> Vec<(Token, usize)> {
    let chars: Vec<char> = text.chars().collect();
    let (mut out, mut i, mut line) = (Vec::new(), 0, 1);
    while i < chars.len() {
        let c = chars[i];
        let next = chars.get(i + 1).copied();
        let start_line = line;
        if c == '\n' {
            line += 1;
            i += 1;
        } else if c.is_whitespace() {
            i += 1;
        } else if c == '/' && next == Some('/') {
            while i < chars.len() && chars[i] != '\n' {
                i += 1;
            }
        } else if c == '/' && next == Some('*') {
            i += 2;
            while i < chars.len() && !(chars[i] == '*' && chars.get(i + 1) == Some(&'/')) {
                line += usize::from(chars[i] == '\n');
                i += 1;
            }
            i += 2;
        } else if c == '"' {
            let (text, end, lines) = string_literal(&chars, i + 1);
            out.push((Token::Text(text), start_line));
            (i, line) = (end, line + lines);
        } else if c.is_ascii_alphabetic() || c == '_' {
            let end = (i..chars.len())
                .find(|&j| !(chars[j].is_ascii_alphanumeric() || chars[j] == '_'))
                .unwrap_or(chars.len());
            out.push((Token::Ident(chars[i..end].iter().collect()), line));
            i = end;
        } else if c.is_ascii_punctuation() {
            out.push((Token::Punct(c), line));
            i += 1;
        } else {
            out.push((Token::Other, line));
            i += 1;
        }
    }
    out
}

/// The string literal starting after its opening quote at `start`: its text (escapes kept as
/// the escaped character), the index after its closing quote, and the newlines it spans.
fn string_literal(chars: &[char], start: usize) -> (String, usize, usize) {
    let (mut text, mut i, mut lines) = (String::new(), start, 0);
    while i < chars.len() && chars[i] != '"' {
        if chars[i] == '\\' && i + 1 < chars.len() {
            i += 1;
        }
        lines += usize::from(chars[i] == '\n');
        text.push(chars[i]);
        i += 1;
    }
    (text, i + 1, lines)
}

/// Scan `geo` (and the `.geo` files it includes) unless `trusted`.
pub fn check_geometry(geo: &Path, trusted: bool) -> Result<()> {
    if trusted {
        return Ok(());
    }
    let root = geo
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."));
    let mut seen = Vec::new();
    scan_file(geo, &root, 0, &mut seen)
}

fn refuse(file: &Path, line: usize, what: &str) -> Error {
    Error::Gmsh(format!(
        "{}:{line}: {what}; a geometry is read as data, so this is refused before gmsh runs. \
         Remove the statement, or pass --trust-geometry if you wrote this file and mean it",
        file.display()
    ))
}

/// Scan one file, then the `.geo` files it includes.
fn scan_file(file: &Path, root: &Path, depth: usize, seen: &mut Vec<PathBuf>) -> Result<()> {
    if seen.len() >= MAX_FILES || depth > MAX_DEPTH {
        return Err(refuse(
            file,
            1,
            &format!("includes nest deeper than {MAX_DEPTH} or name more than {MAX_FILES} files"),
        ));
    }
    seen.push(file.to_path_buf());
    let text = std::fs::read_to_string(file)
        .map_err(|e| Error::Gmsh(format!("cannot read geometry {}: {e}", file.display())))?;
    let here = file.parent().unwrap_or(Path::new("."));
    for (path, line) in scan_text(&text).map_err(|(line, what)| refuse(file, line, &what))? {
        let target = here.join(&path);
        if !inside(root, &target) {
            return Err(refuse(
                file,
                line,
                &format!(
                    "it reads \"{path}\", outside the geometry's folder {}",
                    root.display()
                ),
            ));
        }
        let is_geo = target.extension().is_some_and(|e| e == "geo");
        if is_geo && target.is_file() && !seen.contains(&target) {
            scan_file(&target, root, depth + 1, seen)?;
        }
    }
    Ok(())
}

/// Whether `target` lies inside `root`'s folder tree: by their canonical paths where they
/// exist, else by the path's components (no `..` above `root`, not absolute).
fn inside(root: &Path, target: &Path) -> bool {
    if let (Ok(r), Ok(t)) = (root.canonicalize(), target.canonicalize()) {
        return t.starts_with(r);
    }
    let Ok(relative) = target.strip_prefix(root) else {
        return false;
    };
    let mut depth: i64 = 0;
    for c in relative.components() {
        match c {
            Component::Normal(_) => depth += 1,
            Component::CurDir => {}
            _ => depth -= 1,
        }
        if depth < 0 {
            return false;
        }
    }
    true
}

/// The statements of a `.geo` text: `Ok` with the literal paths it reads (and their lines),
/// or `Err` with the line and what the first refused statement does.
pub fn scan_text(text: &str) -> std::result::Result<Vec<(String, usize)>, (usize, String)> {
    let toks = tokens(text);
    let mut reads = Vec::new();
    for (k, (tok, line)) in toks.iter().enumerate() {
        let Token::Ident(name) = tok else { continue };
        let option = k > 0 && toks[k - 1].0 == Token::Punct('.');
        let field = toks.get(k + 1).is_some_and(|t| t.0 == Token::Punct('.'));
        if option || field {
            continue;
        }
        let name = name.as_str();
        if RUNS.contains(&name) {
            return Err((*line, format!("`{name}` runs a program")));
        }
        if name == "Printf" && redirected(&toks, k) {
            return Err((*line, "`Printf(…) >` writes a file".into()));
        }
        if WRITES.contains(&name) && writes(&toks, k) {
            return Err((*line, format!("`{name}` writes, deletes or creates a file")));
        }
        if READS.contains(&name) {
            match literal_argument(&toks, k) {
                Some(path) => reads.push((path, *line)),
                None => {
                    return Err((
                        *line,
                        format!("`{name}` reads a file named by an expression"),
                    ))
                }
            }
        }
    }
    Ok(reads)
}

/// Whether the `Printf(…)` at `k` is followed by `>` (or `>>`) after its closing parenthesis.
fn redirected(toks: &[(Token, usize)], k: usize) -> bool {
    let mut depth = 0i64;
    for (j, (tok, _)) in toks.iter().enumerate().skip(k + 1) {
        match tok {
            Token::Punct('(') => depth += 1,
            Token::Punct(')') => {
                depth -= 1;
                if depth <= 0 {
                    return toks.get(j + 1).is_some_and(|t| t.0 == Token::Punct('>'));
                }
            }
            Token::Punct(';') if depth <= 0 => return false,
            _ => {}
        }
    }
    false
}

/// Whether the file command at `k` names a file: a string or expression before its `;`
/// (`Delete Physicals;`, `Delete Model;` and `Delete { … }` name none).
fn writes(toks: &[(Token, usize)], k: usize) -> bool {
    match toks.get(k + 1).map(|t| &t.0) {
        Some(Token::Text(_)) | Some(Token::Punct('(')) => true,
        Some(Token::Ident(s)) => toks[k].0 != Token::Ident("Delete".into()) || s == "StrCat",
        _ => false,
    }
}

/// The literal path a reading statement at `k` names: `Include "f";`, `ShapeFromFile("f")`.
fn literal_argument(toks: &[(Token, usize)], k: usize) -> Option<String> {
    let mut next = toks.get(k + 1)?;
    if next.0 == Token::Punct('(') {
        next = toks.get(k + 2)?;
    }
    match &next.0 {
        Token::Text(s) => Some(s.clone()),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refused(text: &str) -> Option<(usize, String)> {
        scan_text(text).err()
    }

    /// TEST GOAL: each statement that runs a program or writes a file is refused with its
    /// line; the same words in comments, strings and option names, `Printf` to the terminal
    /// and `Delete Physicals;` pass.
    #[test]
    fn programs_and_file_writes_are_found_and_their_mentions_are_not() {
        for (text, line) in [
            ("lc = 1;\nSystemCall \"id > f\";", 2),
            ("NonBlockingSystemCall \"x\";", 1),
            ("a = 1;\n\nShell \"x\";", 3),
            ("OnelabRun(\"x\", \"y\");", 1),
            ("Printf(\"%g\", 1) > \"/tmp/x\";", 1),
            ("Printf(\"%g\", f(2)) >> \"/tmp/x\";", 1),
            ("Print \"a.png\";", 1),
            ("Save \"a.msh\";", 1),
            ("DeleteFile \"a\";", 1),
            ("Delete \"a\";", 1),
            ("/* two\nlines */ RenameFile \"a\", \"b\";", 2),
            ("Include StrCat(\"a\", \".geo\");", 1),
        ] {
            assert_eq!(refused(text).map(|r| r.0), Some(line), "{text}");
        }
        for text in [
            "// SystemCall \"id\";\nlc = 1;",
            "/* Shell \"x\"; */",
            "Printf(\"SystemCall %g\", 1);",
            "Print.Width = 100;\nGeneral.SystemCall = 0;",
            "Delete Physicals;",
            "Printf(\"a > b\");",
        ] {
            assert_eq!(refused(text), None, "{text}");
        }
    }

    /// TEST GOAL: `Include` paths are collected with their lines for the folder check.
    #[test]
    fn included_paths_are_collected_with_their_lines() {
        let reads = scan_text("lc = 1;\nInclude \"sub/a.geo\";\nMerge \"b.msh\";");
        assert_eq!(
            reads.ok(),
            Some(vec![("sub/a.geo".into(), 2), ("b.msh".into(), 3)])
        );
    }
}
