//! Regenerate the committed JSON Schemas from the code:
//! `cargo run --release --example write_schemas` writes `docs/pipeline.schema.json` (the
//! pipeline YAML), `docs/summary.schema.json` (a run's summary.json), `docs/modes.schema.json`
//! (modes.json), `docs/compare.schema.json` (compare.json), `docs/study.schema.json` (a study YAML) and
//! `docs/sweep.schema.json` (sweep.json); `hbcontact schema
//! pipeline|summary|modes|compare|study|sweep` prints the same.
//! `tests/docs.rs` fails when the committed files and the
//! code disagree.

use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let docs = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("docs");
    std::fs::create_dir_all(&docs)?;
    for (name, schema) in [
        ("pipeline.schema.json", hbcontact::config::pipeline_schema()),
        ("summary.schema.json", hbcontact::pipeline::summary_schema()),
        (
            "modes.schema.json",
            hbcontact::pipeline::modes::modes_schema(),
        ),
        (
            "compare.schema.json",
            hbcontact::pipeline::compare::compare_schema(),
        ),
        ("study.schema.json", hbcontact::study::study_schema()),
        ("sweep.schema.json", hbcontact::sweep::sweep_schema()),
    ] {
        let path = docs.join(name);
        std::fs::write(&path, serde_json::to_string_pretty(&schema)? + "\n")?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
