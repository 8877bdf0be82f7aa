//! Reading a pipeline: the YAML file (size- and depth-checked, `limits`), the `--set`
//! overrides applied to its tree, and serde's errors explained (the expected names, the file's
//! line and column) before `validate` makes a `Pipeline` of it.

use std::path::Path;

use serde_yaml::Value;

use super::raw::*;
use super::validate::*;
use super::*;
use crate::{Error, Result};

/// The names listed in serde's "expected one of `a`, `b`" / "expected `a` or `b`".
pub(super) fn expected_names(message: &str) -> Vec<String> {
    let Some(pos) = message.find("expected") else {
        return Vec::new();
    };
    message[pos..]
        .split('`')
        .skip(1)
        .step_by(2)
        .map(str::to_string)
        .collect()
}

/// serde's message plus a "did you mean" for unknown keys and values.
pub(super) fn explain(message: &str) -> String {
    let unknown = ["unknown field `", "unknown variant `"]
        .iter()
        .find_map(|p| {
            message.find(p).and_then(|i| {
                let rest = &message[i + p.len()..];
                rest.find('`').map(|j| rest[..j].to_string())
            })
        });
    if message.contains("untagged enum RawHarmonics") {
        return "harmonic_balance.harmonics must be a whole number H (e.g. 20) or a range \
                {min: 10, max: 40}"
            .into();
    }
    let Some(word) = unknown else {
        return message.to_string();
    };
    let best = expected_names(message)
        .into_iter()
        .map(|c| (strsim::jaro_winkler(&word, &c), c))
        .filter(|(s, _)| *s > 0.75)
        .max_by(|a, b| a.0.total_cmp(&b.0));
    match best {
        Some((_, c)) => format!("{message}; did you mean `{c}`?"),
        None => message.to_string(),
    }
}

pub(super) fn yaml_error(path: &Path, e: &serde_yaml::Error, context: Option<&str>) -> Error {
    let location = e
        .location()
        .map(|l| format!("line {}, column {}: ", l.line(), l.column()))
        .unwrap_or_default();
    let message = explain(&e.to_string());
    let message = match context {
        Some(c) => format!("{c}: {message}"),
        None => format!("{location}{message}"),
    };
    config_error(path, message)
}

/// Set `a.b.c` to `value` (a YAML scalar or flow value), creating mappings on the way. A
/// segment of digits indexes an existing list (`boundaries.loads.0.static=[0, 1]`).
pub(super) fn apply_override(root: &mut Value, spec: &str, path: &Path) -> Result<()> {
    let shown = crate::error::excerpt(spec);
    let Some((key, value)) = spec.split_once('=') else {
        return Err(config_error(
            path,
            format!("--set {shown}: expected KEY=VALUE, e.g. --set harmonic_balance.harmonics=20"),
        ));
    };
    super::limits::check_yaml(value, "pipeline")
        .map_err(|m| config_error(path, format!("--set {shown}: {m}")))?;
    let parsed: Value = serde_yaml::from_str(value).map_err(|e| {
        config_error(
            path,
            format!(
                "--set {shown}: the value is not valid YAML: {}",
                crate::error::excerpt(&e.to_string())
            ),
        )
    })?;
    let mut node = root;
    let parts: Vec<&str> = key.trim().split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err(config_error(
            path,
            format!("--set {shown}: empty key segment"),
        ));
    }
    for (i, part) in parts.iter().enumerate() {
        let last = i + 1 == parts.len();
        let so_far = parts[..i].join(".");
        if let Ok(index) = part.parse::<usize>() {
            match node {
                Value::Sequence(list) => {
                    let len = list.len();
                    let Some(entry) = list.get_mut(index) else {
                        return Err(config_error(
                            path,
                            format!(
                                "--set {shown}: {so_far} has {len} entries (indices 0 to {}); to add or remove entries set the whole list, e.g. --set '{so_far}=[...]'",
                                len.saturating_sub(1)
                            ),
                        ));
                    };
                    if last {
                        *entry = parsed;
                        return Ok(());
                    }
                    node = entry;
                    continue;
                }
                _ => {
                    return Err(config_error(
                        path,
                        format!(
                            "--set {shown}: `{part}` indexes a list, but {} is not a list in the pipeline; set the whole value instead, e.g. --set '{}=[...]'",
                            if so_far.is_empty() { "the top level".to_string() } else { so_far.clone() },
                            if so_far.is_empty() { "KEY".to_string() } else { so_far.clone() }
                        ),
                    ));
                }
            }
        }
        if !node.is_mapping() {
            *node = Value::Mapping(Default::default());
        }
        let Value::Mapping(map) = node else {
            unreachable!("just made a mapping")
        };
        let k = Value::String(part.to_string());
        if last {
            map.insert(k, parsed);
            return Ok(());
        }
        node = map.entry(k).or_insert(Value::Null);
    }
    Ok(())
}

/// Read `path`, apply `--set key.path=value` overrides, and validate.
pub fn load_pipeline(path: &Path, overrides: &[String]) -> Result<Pipeline> {
    let text = super::limits::read_yaml(path, "pipeline").map_err(|m| config_error(path, m))?;
    parse_pipeline(path, &text, overrides)
}

/// A pipeline from its YAML `text`, as if read from `path` (relative files resolve from it,
/// errors name it), with the `--set` overrides applied.
pub fn parse_pipeline(path: &Path, text: &str, overrides: &[String]) -> Result<Pipeline> {
    super::limits::check_yaml(text, "pipeline").map_err(|m| config_error(path, m))?;
    let raw: RawPipeline = if overrides.is_empty() {
        serde_yaml::from_str(text).map_err(|e| yaml_error(path, &e, None))?
    } else {
        let mut value: Value =
            serde_yaml::from_str(text).map_err(|e| yaml_error(path, &e, None))?;
        for o in overrides {
            apply_override(&mut value, o, path)?;
        }
        match serde_yaml::from_value(value) {
            Ok(raw) => raw,
            Err(e) => {
                // The file itself may be at fault: then show its line and column.
                if let Err(file_error) = serde_yaml::from_str::<RawPipeline>(text) {
                    if file_error.to_string() == e.to_string() {
                        return Err(yaml_error(path, &file_error, None));
                    }
                }
                let context = format!(
                    "with {}",
                    overrides
                        .iter()
                        .map(|o| format!("--set {}", crate::error::excerpt(o)))
                        .collect::<Vec<_>>()
                        .join(" ")
                );
                return Err(yaml_error(path, &e, Some(&context)));
            }
        }
    };
    let mut pipeline = validate(path, raw)?;
    pipeline.overrides = overrides.to_vec();
    Ok(pipeline)
}
