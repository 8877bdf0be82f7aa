//! Regenerate the committed JSON Schemas from the code:
//! `cargo run --release --example write_schemas` writes `docs/pipeline.schema.json`.
//! `tests/docs.rs` fails when the committed file and the code disagree.

use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let docs = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("docs");
    std::fs::create_dir_all(&docs)?;
    let path = docs.join("pipeline.schema.json");
    let text = serde_json::to_string_pretty(&hbcontact::config::pipeline_schema())? + "\n";
    std::fs::write(&path, text)?;
    println!("wrote {}", path.display());
    Ok(())
}
