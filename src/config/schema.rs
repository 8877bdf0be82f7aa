//! The JSON Schema of the pipeline YAML (`docs/pipeline.schema.json`), generated from the raw
//! serde types so that it cannot drift from what the parser accepts. Editors that speak the
//! YAML language server protocol pick it up from the first line of each pipeline:
//! `# yaml-language-server: $schema=../docs/pipeline.schema.json`.

/// The pipeline's JSON Schema (draft 07) as a JSON value.
pub fn pipeline_schema() -> serde_json::Value {
    serde_json::Value::from(super::raw::raw_schema())
}
