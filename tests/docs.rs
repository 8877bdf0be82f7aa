//! The documentation stays true to the code: the committed JSON Schema is the one the code
//! generates, docs/pipeline.md names every key of it, and relative links resolve.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use serde_json::Value;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
}

const REGENERATE: &str = "regenerate it with `cargo run --release --example write_schemas` \
                          and commit docs/*.schema.json";

/// The committed schema file equals the one the code generates.
fn assert_committed(file: &str, generated: &Value) {
    let path = root().join("docs").join(file);
    let generated = serde_json::to_string_pretty(generated).expect("a schema serializes") + "\n";
    let committed = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}; {REGENERATE}", path.display()));
    if committed != generated {
        let line = committed
            .lines()
            .zip(generated.lines())
            .position(|(a, b)| a != b)
            .map_or_else(
                || "a missing or extra line at the end".to_string(),
                |i| format!("line {}", i + 1),
            );
        panic!("docs/{file} differs from the code's schema (first at {line}): {REGENERATE}");
    }
}

#[test]
fn committed_pipeline_schema_is_the_generated_one() {
    assert_committed(
        "pipeline.schema.json",
        &hbcontact::config::pipeline_schema(),
    );
}

/// TEST GOAL: the summary's schema in docs/ is the one `hbcontact schema summary` prints and
/// the typed `Summary` serializes to, so scripts reading summary.json can rely on it.
#[test]
fn committed_summary_schema_is_the_generated_one() {
    assert_committed(
        "summary.schema.json",
        &hbcontact::pipeline::summary_schema(),
    );
}

/// TEST GOAL: the schemas of modes.json and compare.json in docs/ are the ones the typed
/// `ModesSummary` and `Comparison` serialize to (`hbcontact schema modes|compare`).
#[test]
fn committed_modes_and_compare_schemas_are_the_generated_ones() {
    assert_committed(
        "modes.schema.json",
        &hbcontact::pipeline::modes::modes_schema(),
    );
    assert_committed(
        "compare.schema.json",
        &hbcontact::pipeline::compare::compare_schema(),
    );
}

/// TEST GOAL: the schema of a sweep's sweep.json in docs/ is the one the typed
/// `SweepSummary` serializes to (`hbcontact schema sweep`).
#[test]
fn committed_sweep_schema_is_the_generated_one() {
    assert_committed("sweep.schema.json", &hbcontact::sweep::sweep_schema());
}

/// TEST GOAL: the study file's schema in docs/ is the one `hbcontact schema study` prints,
/// and docs/study.md names every key of it.
#[test]
fn committed_study_schema_is_the_generated_one_and_documented() {
    let schema = hbcontact::study::study_schema();
    assert_committed("study.schema.json", &schema);
    let definitions = schema.get("definitions").cloned().unwrap_or(Value::Null);
    let mut paths = BTreeSet::new();
    key_paths(&schema, &definitions, "", &mut paths);
    assert!(paths.contains("accuracy.ladders.key"), "{paths:?}");
    let doc = read(&root().join("docs/study.md"));
    let missing: Vec<&String> = paths
        .iter()
        .filter(|p| !doc.contains(&format!("`{p}`")))
        .collect();
    assert!(
        missing.is_empty(),
        "docs/study.md does not document these study keys (write each as `key.path`): {missing:?}"
    );
}

/// Every key path of the schema (`a.b.c`; list items add no segment), following `$ref`,
/// `allOf`/`anyOf`/`oneOf` and `items`. Maps with free keys (`additionalProperties` schemas)
/// end the path.
fn key_paths(schema: &Value, definitions: &Value, prefix: &str, out: &mut BTreeSet<String>) {
    let Some(object) = schema.as_object() else {
        return;
    };
    if let Some(reference) = object.get("$ref").and_then(Value::as_str) {
        let name = reference
            .rsplit('/')
            .next()
            .expect("rsplit yields at least one piece");
        let target = definitions
            .get(name)
            .unwrap_or_else(|| panic!("unresolved $ref {reference}"));
        key_paths(target, definitions, prefix, out);
    }
    for combinator in ["allOf", "anyOf", "oneOf"] {
        for sub in object
            .get(combinator)
            .and_then(Value::as_array)
            .into_iter()
            .flatten()
        {
            key_paths(sub, definitions, prefix, out);
        }
    }
    if let Some(items) = object.get("items") {
        key_paths(items, definitions, prefix, out);
    }
    if let Some(properties) = object.get("properties").and_then(Value::as_object) {
        for (key, sub) in properties {
            let path = if prefix.is_empty() {
                key.clone()
            } else {
                format!("{prefix}.{key}")
            };
            out.insert(path.clone());
            key_paths(sub, definitions, &path, out);
        }
    }
}

#[test]
fn pipeline_reference_names_every_key() {
    let schema = hbcontact::config::pipeline_schema();
    let definitions = schema.get("definitions").cloned().unwrap_or(Value::Null);
    let mut paths = BTreeSet::new();
    key_paths(&schema, &definitions, "", &mut paths);
    for expected in [
        "harmonic_balance.solver.c_scale",
        "contact.obstacle.circle.body_inside",
        "contact.obstacle.curve",
        "boundaries.loads.harmonics.cos",
        "output.fields",
    ] {
        assert!(
            paths.contains(expected),
            "the schema walk missed {expected}: {paths:?}"
        );
    }
    let doc = read(&root().join("docs/pipeline.md"));
    let missing: Vec<&String> = paths
        .iter()
        .filter(|p| !doc.contains(&format!("`{p}`")))
        .collect();
    assert!(
        missing.is_empty(),
        "docs/pipeline.md does not document these pipeline keys (write each as `key.path`): {missing:?}"
    );
}

/// The targets of inline links `[text](target)` and reference definitions `[label]: target`,
/// outside fenced code blocks and code spans.
fn link_targets(markdown: &str) -> Vec<String> {
    let mut targets = Vec::new();
    let mut fenced = false;
    for line in markdown.lines() {
        let trimmed = line.trim_start();
        if trimmed.starts_with("```") || trimmed.starts_with("~~~") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        // Drop code spans: text between backticks.
        let text: String = line
            .split('`')
            .enumerate()
            .filter(|(i, _)| i % 2 == 0)
            .map(|(_, s)| s)
            .collect::<Vec<_>>()
            .join(" ");
        if let Some(rest) = text.trim_start().strip_prefix('[') {
            if let Some((_, after)) = rest.split_once("]:") {
                if let Some(target) = after.split_whitespace().next() {
                    targets.push(target.trim_matches(['<', '>']).to_string());
                }
            }
        }
        let mut rest = text.as_str();
        while let Some(i) = rest.find("](") {
            let after = &rest[i + 2..];
            if let Some(bracketed) = after.strip_prefix('<') {
                let Some(end) = bracketed.find('>') else {
                    break;
                };
                targets.push(bracketed[..end].to_string());
                rest = &bracketed[end..];
                continue;
            }
            let Some(end) = after.find(')') else { break };
            let target = after[..end].split_whitespace().next().unwrap_or("");
            targets.push(target.to_string());
            rest = &after[end..];
        }
    }
    targets
}

/// README.md and docs/*.md.
fn markdown_files() -> Vec<PathBuf> {
    let root = root();
    let mut files = vec![root.join("README.md")];
    let docs = root.join("docs");
    let mut entries: Vec<PathBuf> = std::fs::read_dir(&docs)
        .unwrap_or_else(|e| panic!("cannot list {}: {e}", docs.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    entries.sort();
    files.extend(entries);
    files
}

#[test]
fn relative_links_resolve() {
    let root = root();
    let files = markdown_files();
    let mut broken = Vec::new();
    for file in &files {
        let base = file.parent().unwrap_or(&root);
        for target in link_targets(&read(file)) {
            let lower = target.to_ascii_lowercase();
            if target.is_empty()
                || target.starts_with('#')
                || lower.starts_with("http://")
                || lower.starts_with("https://")
                || lower.starts_with("mailto:")
            {
                continue;
            }
            let path = target.split('#').next().unwrap_or("");
            if path.is_empty() {
                continue;
            }
            if !base.join(path).exists() {
                broken.push(format!("{}: {target}", file.display()));
            }
        }
    }
    assert!(broken.is_empty(), "broken relative links: {broken:#?}");
}

/// Every `file.rs::name` in `markdown`, as (file.rs, name).
fn cited_functions(markdown: &str) -> Vec<(String, String)> {
    let word = |c: char| c.is_ascii_alphanumeric() || c == '_';
    let mut cited = Vec::new();
    for (at, _) in markdown.match_indices(".rs::") {
        let before = &markdown[..at];
        let stem_start = before
            .char_indices()
            .rev()
            .find(|&(_, c)| !(word(c) || c == '/'))
            .map_or(0, |(i, c)| i + c.len_utf8());
        let stem = before[stem_start..].rsplit('/').next().unwrap_or("");
        let after = &markdown[at + ".rs::".len()..];
        let name: String = after.chars().take_while(|&c| word(c)).collect();
        if !stem.is_empty() && !name.is_empty() {
            cited.push((format!("{stem}.rs"), name));
        }
    }
    cited
}

/// Every .rs file under `dir`, recursively.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for path in entries.filter_map(|e| e.ok().map(|e| e.path())) {
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|x| x == "rs") {
            out.push(path);
        }
    }
}

/// TEST GOAL: every test (or function) the README and docs cite as `file.rs::name`, the
/// tests that hold their claimed numbers, exists as `fn name` in a file of that name under
/// tests/, src/ or benches/ (a renamed test left the README citing one that did not exist).
#[test]
fn every_function_the_docs_cite_exists() {
    let root = root();
    let mut sources = Vec::new();
    for dir in ["tests", "src", "benches"] {
        rust_files(&root.join(dir), &mut sources);
    }
    let texts: Vec<(String, String)> = sources
        .iter()
        .map(|p| {
            let name = p
                .file_name()
                .map_or(String::new(), |n| n.to_string_lossy().into());
            (name, read(p))
        })
        .collect();
    let defines = |file: &str, name: &str| {
        let needle = format!("fn {name}");
        texts.iter().filter(|(f, _)| f == file).any(|(_, text)| {
            text.match_indices(&needle).any(|(i, _)| {
                let next = text[i + needle.len()..].chars().next();
                next.is_some_and(|c| c == '(' || c == '<')
            })
        })
    };
    let (mut missing, mut checked) = (Vec::new(), 0);
    for file in markdown_files() {
        for (source, name) in cited_functions(&read(&file)) {
            checked += 1;
            if !defines(&source, &name) {
                missing.push(format!("{}: {source}::{name}", file.display()));
            }
        }
    }
    assert!(
        checked > 100,
        "only {checked} citations found: is the parser broken?"
    );
    assert!(missing.is_empty(), "cited but not defined: {missing:#?}");
}

#[test]
fn cited_functions_are_found_with_and_without_paths() {
    let md = "held by `hard.rs::a_case` and (tests/sweep.rs::b_case_2), not `c.rs` or x.rs::";
    let cited = cited_functions(md);
    let expected = [("hard.rs", "a_case"), ("sweep.rs", "b_case_2")];
    let expected: Vec<(String, String)> = expected
        .iter()
        .map(|(f, n)| (f.to_string(), n.to_string()))
        .collect();
    assert_eq!(cited, expected);
}

#[test]
fn link_extraction_sees_inline_and_reference_links_only() {
    let md = "See [a](a.md#x) and [b](<b c.md> \"t\"), not `[c](c.md)`.\n\
              [d]: d.md\n```\n[e](e.md)\n```\n";
    assert_eq!(link_targets(md), ["a.md#x", "b c.md", "d.md"]);
}

#[test]
fn shipped_pipelines_name_the_schema() {
    let dir = root().join("pipelines");
    let mut count = 0;
    for entry in std::fs::read_dir(&dir).expect("pipelines/ exists") {
        let path = entry.expect("a directory entry").path();
        if path.extension().is_none_or(|x| x != "yaml") {
            continue;
        }
        count += 1;
        let text = read(&path);
        assert_eq!(
            text.lines().next(),
            Some("# yaml-language-server: $schema=../docs/pipeline.schema.json"),
            "{}: the first line must point editors to the schema",
            path.display()
        );
    }
    assert!(count > 0, "no pipelines found");
}
