//! Fuzzing the readers of user files (#9 item 6) with proptest: mutated pipeline and study
//! YAML (from the shipped `pipelines/**/*.yaml` and `studies/*.yaml`) and mutated gmsh `.msh`
//! files (from small meshes gmsh wrote, `tests/data/fuzz/`). The property: the reader never
//! panics, and ends either in a value whose invariants hold (finite numbers, indices in range)
//! or in a bad-input error (exit class 2) that names the file and stays short. A `.msh`
//! reader also never holds more memory than a small multiple of the file's size, whatever
//! count the file claims. A mutated `sweep.json` (from a real sweep stopped at its point
//! budget) is resumed, in process, by `hbcontact sweep --resume`: it continues or is refused
//! with exit class 2 naming the file or its saved point, and no allocation exceeds 1 GiB.
//! A study's records (from a small accuracy study): a mutated `point.json` or an accuracy
//! rung's `amplitudes.vtu` is read back as `study --merge` reads it: the table and the errors
//! are built from values a run writes, or it is refused with exit class 2 naming the file and
//! the fix, holding at most a small multiple of the file's size.
//!
//! `make test` runs 256 cases per target (proptest's default); the long run is
//! `PROPTEST_CASES=100000 cargo test --release --test fuzz`. Failing inputs proptest finds are
//! kept in `tests/fuzz.proptest-regressions` (replayed first on every run); each bug fixed also
//! has a named test below (`regression_*`).

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::{Path, PathBuf};

use hbcontact::config::{parse_pipeline, Pipeline};
use hbcontact::mesh::msh::read_msh;
use hbcontact::mesh::Mesh2d;
use hbcontact::study::{parse_study, plan::plan, Study};
use proptest::prelude::*;
use proptest::sample::Index;
use serde_yaml::Value;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

// ---------------------------------------------------------------------------------------------
// Memory: the largest amount this thread holds at once while `measure` runs.

/// Counts the bytes the measuring thread holds; refuses (aborting the test, with the size in
/// the message) any single request above `REFUSED_BYTES` so a corrupted count cannot take
/// the shared machine's memory.
struct Counting;

const REFUSED_BYTES: usize = 1 << 30;

thread_local! {
    static MEASURING: Cell<bool> = const { Cell::new(false) };
    static HELD: Cell<isize> = const { Cell::new(0) };
    static PEAK: Cell<isize> = const { Cell::new(0) };
}

fn note(delta: isize) {
    if MEASURING.with(Cell::get) {
        let held = HELD.with(|h| {
            h.set(h.get() + delta);
            h.get()
        });
        PEAK.with(|p| p.set(p.get().max(held)));
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if layout.size() > REFUSED_BYTES && MEASURING.with(Cell::get) {
            return std::ptr::null_mut();
        }
        note(layout.size() as isize);
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        note(-(layout.size() as isize));
        System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > REFUSED_BYTES && MEASURING.with(Cell::get) {
            return std::ptr::null_mut();
        }
        note(new_size as isize - layout.size() as isize);
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// `f`'s result and the most bytes this thread held at once (beyond what it held before).
fn measure<T>(f: impl FnOnce() -> T) -> (T, usize) {
    HELD.with(|h| h.set(0));
    PEAK.with(|p| p.set(0));
    MEASURING.with(|m| m.set(true));
    let out = f();
    MEASURING.with(|m| m.set(false));
    (out, PEAK.with(Cell::get).max(0) as usize)
}

/// proptest's defaults (`PROPTEST_CASES`, 256 without it), failures kept beside this file.
fn config() -> ProptestConfig {
    ProptestConfig {
        failure_persistence: Some(Box::new(
            proptest::test_runner::FileFailurePersistence::WithSource("proptest-regressions"),
        )),
        ..ProptestConfig::default()
    }
}

// ---------------------------------------------------------------------------------------------
// YAML mutations.

/// A value put in place of a node of the YAML tree.
#[derive(Clone, Debug)]
enum Replacement {
    Nan,
    Inf,
    NegInf,
    Huge,
    HugeInt,
    BigInt,
    Negative,
    Zero,
    LongText,
    Text,
    EmptyList,
    EmptyMap,
    Null,
    Bool,
}

impl Replacement {
    fn yaml(&self, old: &Value) -> Value {
        let parse = |s: &str| serde_yaml::from_str::<Value>(s).expect("a literal");
        match self {
            Replacement::Nan => parse(".nan"),
            Replacement::Inf => parse(".inf"),
            Replacement::NegInf => parse("-.inf"),
            Replacement::Huge => parse("1.0e300"),
            Replacement::HugeInt => parse("18446744073709551615"),
            Replacement::BigInt => parse("1000000000"),
            Replacement::Negative => match old.as_f64() {
                Some(v) if v != 0.0 => parse(&format!("{:e}", -v)),
                _ => parse("-1"),
            },
            Replacement::Zero => parse("0"),
            Replacement::LongText => Value::String("x".repeat(20_000)),
            Replacement::Text => Value::String("word".into()),
            Replacement::EmptyList => parse("[]"),
            Replacement::EmptyMap => parse("{}"),
            Replacement::Null => Value::Null,
            Replacement::Bool => Value::Bool(true),
        }
    }
}

fn replacement() -> impl Strategy<Value = Replacement> {
    prop_oneof![
        Just(Replacement::Nan),
        Just(Replacement::Inf),
        Just(Replacement::NegInf),
        Just(Replacement::Huge),
        Just(Replacement::HugeInt),
        Just(Replacement::BigInt),
        Just(Replacement::Negative),
        Just(Replacement::Zero),
        Just(Replacement::LongText),
        Just(Replacement::Text),
        Just(Replacement::EmptyList),
        Just(Replacement::EmptyMap),
        Just(Replacement::Null),
        Just(Replacement::Bool),
    ]
}

/// One mutation: of the YAML tree (a node replaced, a key deleted), then of the text.
#[derive(Clone, Debug)]
enum Edit {
    Replace(Index, Replacement),
    DeleteKey(Index),
    DuplicateLine(Index),
    DeleteLine(Index),
    Truncate(Index),
    FlipByte(Index, u8),
    InsertBytes(Index, Vec<u8>),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        6 => (any::<Index>(), replacement()).prop_map(|(i, r)| Edit::Replace(i, r)),
        2 => any::<Index>().prop_map(Edit::DeleteKey),
        1 => any::<Index>().prop_map(Edit::DuplicateLine),
        1 => any::<Index>().prop_map(Edit::DeleteLine),
        1 => any::<Index>().prop_map(Edit::Truncate),
        1 => (any::<Index>(), 1..=255u8).prop_map(|(i, m)| Edit::FlipByte(i, m)),
        1 => (any::<Index>(), prop::collection::vec(any::<u8>(), 1..8))
            .prop_map(|(i, b)| Edit::InsertBytes(i, b)),
    ]
}

/// A step into a YAML tree: a mapping key or a sequence index.
#[derive(Clone, Debug)]
enum Step {
    Key(Value),
    At(usize),
}

/// Every node's path, parents before children.
fn paths(v: &Value, prefix: &mut Vec<Step>, out: &mut Vec<Vec<Step>>) {
    out.push(prefix.clone());
    match v {
        Value::Mapping(m) => {
            for (k, child) in m {
                prefix.push(Step::Key(k.clone()));
                paths(child, prefix, out);
                prefix.pop();
            }
        }
        Value::Sequence(s) => {
            for (i, child) in s.iter().enumerate() {
                prefix.push(Step::At(i));
                paths(child, prefix, out);
                prefix.pop();
            }
        }
        _ => {}
    }
}

fn node<'a>(v: &'a mut Value, path: &[Step]) -> Option<&'a mut Value> {
    path.iter().try_fold(v, |v, step| match step {
        Step::Key(k) => v.as_mapping_mut()?.get_mut(k),
        Step::At(i) => v.as_sequence_mut()?.get_mut(*i),
    })
}

/// The `--set` key of a path (`harmonic_balance.solver.tolerance`, `boundaries.loads.0.group`).
fn dotted(path: &[Step]) -> Option<String> {
    let parts: Option<Vec<String>> = path
        .iter()
        .map(|s| match s {
            Step::Key(Value::String(k)) => Some(k.clone()),
            Step::At(i) => Some(i.to_string()),
            Step::Key(_) => None,
        })
        .collect();
    parts.filter(|p| !p.is_empty()).map(|p| p.join("."))
}

fn edit_tree(tree: &mut Value, e: &Edit) {
    let mut all = Vec::new();
    paths(tree, &mut Vec::new(), &mut all);
    match e {
        Edit::Replace(at, r) => {
            let path = &all[at.index(all.len())];
            if let Some(n) = node(tree, path) {
                *n = r.yaml(n);
            }
        }
        Edit::DeleteKey(at) => {
            let keyed: Vec<&Vec<Step>> = all
                .iter()
                .filter(|p| matches!(p.last(), Some(Step::Key(_))))
                .collect();
            if keyed.is_empty() {
                return;
            }
            let path = keyed[at.index(keyed.len())];
            let (Some(Step::Key(k)), parent) = (path.last(), &path[..path.len() - 1]) else {
                return;
            };
            if let Some(m) = node(tree, parent).and_then(Value::as_mapping_mut) {
                m.remove(k);
            }
        }
        _ => {}
    }
}

fn edit_text(bytes: &mut Vec<u8>, e: &Edit) {
    let lines = |b: &[u8]| -> Vec<(usize, usize)> {
        let mut out = Vec::new();
        let mut start = 0;
        for (i, &c) in b.iter().enumerate() {
            if c == b'\n' {
                out.push((start, i + 1));
                start = i + 1;
            }
        }
        if start < b.len() {
            out.push((start, b.len()));
        }
        out
    };
    match e {
        Edit::DuplicateLine(at) | Edit::DeleteLine(at) => {
            let l = lines(bytes);
            if l.is_empty() {
                return;
            }
            let (s, t) = l[at.index(l.len())];
            if matches!(e, Edit::DuplicateLine(_)) {
                let line = bytes[s..t].to_vec();
                bytes.splice(t..t, line);
            } else {
                bytes.drain(s..t);
            }
        }
        Edit::Truncate(at) => bytes.truncate(at.index(bytes.len() + 1)),
        Edit::FlipByte(at, mask) if !bytes.is_empty() => {
            let i = at.index(bytes.len());
            bytes[i] ^= mask;
        }
        Edit::InsertBytes(at, b) => {
            let i = at.index(bytes.len() + 1);
            bytes.splice(i..i, b.iter().copied());
        }
        _ => {}
    }
}

/// The seed's text with the edits: tree edits on the parsed YAML (then written out again),
/// text edits on the bytes. Without tree edits the original text (comments, layout) is kept.
fn mutate_yaml(seed: &str, edits: &[Edit]) -> (Vec<u8>, Vec<Vec<Step>>) {
    let tree_edits: Vec<&Edit> = edits
        .iter()
        .filter(|e| matches!(e, Edit::Replace(..) | Edit::DeleteKey(_)))
        .collect();
    let mut tree: Value = serde_yaml::from_str(seed).expect("a shipped file parses");
    let mut bytes = if tree_edits.is_empty() {
        seed.as_bytes().to_vec()
    } else {
        for e in tree_edits {
            edit_tree(&mut tree, e);
        }
        serde_yaml::to_string(&tree)
            .expect("a YAML tree writes")
            .into_bytes()
    };
    for e in edits {
        edit_text(&mut bytes, e);
    }
    let mut all = Vec::new();
    paths(&tree, &mut Vec::new(), &mut all);
    (bytes, all)
}

fn yaml_files(dirs: &[&str]) -> Vec<(PathBuf, String)> {
    let mut files: Vec<PathBuf> = dirs
        .iter()
        .flat_map(|d| std::fs::read_dir(root().join(d)).expect("a shipped directory"))
        .map(|e| e.expect("a directory entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "yaml"))
        .collect();
    files.sort();
    files
        .into_iter()
        .map(|p| {
            let text = std::fs::read_to_string(&p).expect("a shipped file reads");
            (p, text)
        })
        .collect()
}

/// A `--set KEY=VALUE` built from a node of the seed and a replacement.
fn override_of(paths: &[Vec<Step>], at: &Index, r: &Replacement) -> Option<String> {
    let key = dotted(&paths[at.index(paths.len())])?;
    let value = serde_yaml::to_string(&r.yaml(&Value::Null)).ok()?;
    Some(format!("{key}={}", value.trim_end()))
}

/// The property of every error a reader returns for bad input.
fn check_error(file: &Path, e: &hbcontact::Error) -> std::result::Result<(), TestCaseError> {
    let text = e.to_string();
    prop_assert_eq!(e.exit_code(), 2, "bad input is exit class 2: {}", text);
    prop_assert!(
        text.contains(&file.display().to_string()),
        "the error names the file {}: {}",
        file.display(),
        text
    );
    let after = text
        .split_once(&file.display().to_string())
        .map_or("", |(_, after)| after);
    prop_assert!(
        after.trim_start_matches(':').trim().len() >= 10,
        "the error says what is wrong: {}",
        text
    );
    prop_assert!(
        text.chars().count() <= 5000,
        "a short error: {} characters",
        text.len()
    );
    Ok(())
}

/// A validated pipeline's numbers are finite and its limits hold.
fn check_pipeline(p: &Pipeline) -> std::result::Result<(), TestCaseError> {
    let m = &p.material;
    let finite = [
        m.youngs_modulus,
        m.poisson_ratio,
        m.density,
        m.thickness,
        p.harmonic_balance.frequency,
        p.harmonic_balance.solver.tolerance,
        p.harmonic_balance.solver.c_scale,
        p.harmonic_balance.solver.max_seconds,
        p.geometry.gmsh_timeout,
    ];
    prop_assert!(finite.iter().all(|v| v.is_finite()), "{:?}", finite);
    prop_assert!(p.geometry.parameters.values().all(|v| v.is_finite()));
    prop_assert!(p
        .geometry
        .mesh_size
        .is_none_or(|h| h > 0.0 && h.is_finite()));
    let loads = p.boundaries.loads.iter().flat_map(|l| {
        let s = &l.signal;
        s.static_part.into_iter().chain(
            s.harmonics
                .iter()
                .flat_map(|(_, c, d)| c.iter().chain(d).copied()),
        )
    });
    prop_assert!(loads.into_iter().all(f64::is_finite));
    prop_assert!(p.harmonic_balance.harmonics <= 1000);
    prop_assert!(p.output.frames >= 1);
    Ok(())
}

fn check_study(study: &Study) -> std::result::Result<(), TestCaseError> {
    for p in &study.parameters {
        prop_assert!(!p.values.is_empty());
        prop_assert!(p
            .values
            .iter()
            .all(|v| v.number().is_none_or(f64::is_finite)));
    }
    Ok(())
}

fn pipeline_case(
    (path, seed): &(PathBuf, String),
    edits: &[Edit],
    set: &Option<(Index, Replacement)>,
) -> std::result::Result<(), TestCaseError> {
    let (bytes, all) = mutate_yaml(seed, edits);
    let text = String::from_utf8_lossy(&bytes);
    let overrides: Vec<String> = set
        .iter()
        .filter_map(|(at, r)| override_of(&all, at, r))
        .collect();
    match parse_pipeline(path, &text, &overrides) {
        Ok(p) => check_pipeline(&p),
        Err(e) => check_error(path, &e),
    }
}

/// Studies whose points the fuzz resolves (each point loads the pipeline); larger ones are
/// only validated.
const PLANNED_POINTS: usize = 200;

fn study_case(
    (path, seed): &(PathBuf, String),
    edits: &[Edit],
) -> std::result::Result<(), TestCaseError> {
    let (bytes, _) = mutate_yaml(seed, edits);
    let text = String::from_utf8_lossy(&bytes);
    let study = match parse_study(path, &text, &[]) {
        Ok(s) => s,
        Err(e) => return check_error(path, &e),
    };
    check_study(&study)?;
    prop_assert!(study.point_count() <= hbcontact::study::spec::MAX_POINTS);
    if study.point_count() > PLANNED_POINTS {
        return Ok(());
    }
    match plan(&study) {
        Ok(points) => {
            prop_assert_eq!(points.len(), study.point_count());
            Ok(())
        }
        // A point's pipeline error names the study file, as the study's own errors do.
        Err(e) => check_error(path, &e),
    }
}

proptest! {
    #![proptest_config(config())]
    /// TEST GOAL: a mutated pipeline YAML (values made NaN, ±Inf, huge, negative, zero, of
    /// the wrong type; keys deleted; lines duplicated or deleted; truncated; bytes flipped or
    /// inserted; a mutated `--set`) never panics: it loads into a pipeline whose numbers are
    /// finite, or fails with a bad-input error naming the file.
    #[test]
    fn mutated_pipelines_load_or_fail_naming_the_file(
        seed in any::<Index>(),
        edits in prop::collection::vec(edit(), 1..4),
        set in prop::option::weighted(0.2, (any::<Index>(), replacement())),
    ) {
        let seeds = yaml_files(&["pipelines", "pipelines/hard"]);
        pipeline_case(&seeds[seed.index(seeds.len())], &edits, &set)?;
    }

    /// TEST GOAL: a mutated study YAML never panics and never expands into more points than
    /// the limit: it loads (and its points resolve, or fail naming the study file), or fails
    /// with a bad-input error naming the file.
    #[test]
    fn mutated_studies_load_or_fail_naming_the_file(
        seed in any::<Index>(),
        edits in prop::collection::vec(edit(), 1..4),
    ) {
        let seeds = yaml_files(&["studies", "tests/data/fuzz"]);
        study_case(&seeds[seed.index(seeds.len())], &edits)?;
    }
}

// ---------------------------------------------------------------------------------------------
// .msh mutations.

/// One mutation of a `.msh` file's bytes.
#[derive(Clone, Debug)]
enum MshEdit {
    Truncate(Index),
    FlipByte(Index, u8),
    InsertBytes(Index, Vec<u8>),
    DeleteRange(Index, usize),
    /// Replace a whitespace-separated token (a count, tag, element type, coordinate).
    Token(Index, String),
    /// Overwrite 8 bytes with a little-endian number (a binary count or tag).
    Word(Index, u64),
    DuplicateLine(Index),
}

fn token() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("0".to_string()),
        Just("-1".to_string()),
        Just("18446744073709551615".to_string()),
        Just("9223372036854775807".to_string()),
        Just("4294967296".to_string()),
        Just("1000000000".to_string()),
        Just("nan".to_string()),
        Just("inf".to_string()),
        Just("1e308".to_string()),
        Just("2 1".to_string()),
        (0..40u32).prop_map(|n| n.to_string()),
    ]
}

fn msh_edit() -> impl Strategy<Value = MshEdit> {
    prop_oneof![
        1 => any::<Index>().prop_map(MshEdit::Truncate),
        2 => (any::<Index>(), 1..=255u8).prop_map(|(i, m)| MshEdit::FlipByte(i, m)),
        1 => (any::<Index>(), prop::collection::vec(any::<u8>(), 1..8))
            .prop_map(|(i, b)| MshEdit::InsertBytes(i, b)),
        1 => (any::<Index>(), 1..64usize).prop_map(|(i, n)| MshEdit::DeleteRange(i, n)),
        4 => (any::<Index>(), token()).prop_map(|(i, t)| MshEdit::Token(i, t)),
        2 => (any::<Index>(), prop_oneof![
            Just(u64::MAX), Just(1u64 << 40), Just(1u64 << 32), Just(0), 0..64u64
        ]).prop_map(|(i, w)| MshEdit::Word(i, w)),
        1 => any::<Index>().prop_map(MshEdit::DuplicateLine),
    ]
}

/// Byte ranges of the whitespace-separated tokens.
fn tokens(b: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = None;
    for (i, c) in b.iter().enumerate() {
        match (c.is_ascii_whitespace(), start) {
            (false, None) => start = Some(i),
            (true, Some(s)) => {
                out.push((s, i));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        out.push((s, b.len()));
    }
    out
}

fn edit_msh(bytes: &mut Vec<u8>, e: &MshEdit) {
    let n = bytes.len();
    match e {
        MshEdit::Truncate(at) => bytes.truncate(at.index(n + 1)),
        MshEdit::FlipByte(at, mask) if n > 0 => bytes[at.index(n)] ^= mask,
        MshEdit::InsertBytes(at, b) => {
            let i = at.index(n + 1);
            bytes.splice(i..i, b.iter().copied());
        }
        MshEdit::DeleteRange(at, len) if n > 0 => {
            let i = at.index(n);
            bytes.drain(i..(i + len).min(n));
        }
        MshEdit::Token(at, t) => {
            let all = tokens(bytes);
            if !all.is_empty() {
                let (s, end) = all[at.index(all.len())];
                bytes.splice(s..end, t.bytes());
            }
        }
        MshEdit::Word(at, w) if n >= 8 => {
            let i = at.index(n - 7);
            bytes[i..i + 8].copy_from_slice(&w.to_le_bytes());
        }
        MshEdit::DuplicateLine(at) => edit_text(bytes, &Edit::DuplicateLine(*at)),
        _ => {}
    }
}

/// A mesh read from a file is usable: finite coordinates, every index in range.
fn check_mesh(mesh: &Mesh2d) -> std::result::Result<(), TestCaseError> {
    let n = mesh.nodes.len();
    prop_assert!(mesh.nodes.iter().flatten().all(|x| x.is_finite()));
    prop_assert!(!mesh.cells.is_empty());
    for c in &mesh.cells {
        prop_assert_eq!(c.nodes.len(), c.kind.nodes_per_cell());
        prop_assert!(c.nodes.iter().all(|&i| i < n));
    }
    for cells in mesh.cell_groups.values() {
        prop_assert!(cells.iter().all(|&i| i < mesh.cells.len()));
    }
    for nodes in mesh.node_groups.values() {
        prop_assert!(nodes.iter().all(|&i| i < n));
    }
    for edges in mesh.edge_groups.values() {
        prop_assert!(edges.iter().flat_map(|e| &e.nodes).all(|&i| i < n));
    }
    Ok(())
}

/// The most a reader may hold while reading a file of `len` bytes: what the seeds need
/// (measured: 7 and 12 bytes per file byte, printed by `fuzz_seeds_load_unmutated`) with
/// room, plus a fixed allowance.
fn memory_allowance(len: usize) -> usize {
    64 * len + (256 << 10)
}

fn msh_seeds() -> Vec<(String, Vec<u8>)> {
    ["strip_wall_order2.msh", "strip_wall_quads_binary.msh"]
        .iter()
        .map(|name| {
            let bytes = std::fs::read(root().join("tests/data/fuzz").join(name)).expect("seed");
            (name.to_string(), bytes)
        })
        .collect()
}

fn scratch(name: &str) -> PathBuf {
    let dir = root().join("output/test-fuzz");
    std::fs::create_dir_all(&dir).expect("scratch directory");
    let thread = format!("{:?}", std::thread::current().id());
    let id: String = thread.chars().filter(char::is_ascii_digit).collect();
    dir.join(format!("{}-{id}-{name}", std::process::id()))
}

fn msh_case(bytes: &[u8], name: &str) -> std::result::Result<(), TestCaseError> {
    let path = scratch(name);
    std::fs::write(&path, bytes).expect("scratch write");
    let (result, held) = measure(|| read_msh(&path));
    prop_assert!(
        held <= memory_allowance(bytes.len()),
        "reading {} bytes held {} bytes",
        bytes.len(),
        held
    );
    match result {
        Ok(mesh) => check_mesh(&mesh),
        Err(e) => check_error(&path, &e),
    }
}

proptest! {
    #![proptest_config(config())]
    /// TEST GOAL: a mutated `.msh` (truncated; bytes flipped, inserted or deleted; counts, tags,
    /// element types and coordinates replaced by 0, −1, huge values, NaN or Inf; binary words
    /// overwritten; lines duplicated) never panics, never holds more than a small multiple of
    /// the file's size, and reads into a usable mesh or fails with an error naming the file.
    #[test]
    fn mutated_msh_files_read_or_fail_naming_the_file(
        seed in any::<Index>(),
        edits in prop::collection::vec(msh_edit(), 1..4),
    ) {
        let seeds = msh_seeds();
        let (name, mut bytes) = seeds[seed.index(seeds.len())].clone();
        for e in &edits {
            edit_msh(&mut bytes, e);
        }
        msh_case(&bytes, &name)?;
    }
}

/// TEST GOAL: the fuzz seeds are valid (every shipped pipeline and study loads, every seed
/// mesh reads, within the memory allowance), so the mutations start from real input.
#[test]
fn fuzz_seeds_load_unmutated() {
    for (path, text) in yaml_files(&["pipelines", "pipelines/hard"]) {
        parse_pipeline(&path, &text, &[]).unwrap_or_else(|e| panic!("{e}"));
    }
    for (path, text) in yaml_files(&["studies", "tests/data/fuzz"]) {
        let s = parse_study(&path, &text, &[]).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(plan(&s).map(|p| p.len()).ok(), Some(s.point_count()));
    }
    for (name, bytes) in msh_seeds() {
        let path = scratch(&name);
        std::fs::write(&path, &bytes).unwrap();
        let (mesh, held) = measure(|| read_msh(&path));
        let mesh = mesh.unwrap_or_else(|e| panic!("{e}"));
        assert!(mesh.cells.len() >= 4, "{name}: {} cells", mesh.cells.len());
        assert!(
            held <= memory_allowance(bytes.len()),
            "{name}: {held} bytes"
        );
        eprintln!(
            "{name}: {} bytes held {held} bytes ({:.0} per file byte)",
            bytes.len(),
            held as f64 / bytes.len() as f64
        );
    }
}

// ---------------------------------------------------------------------------------------------
// sweep.json mutations: a saved sweep resumed.

/// This process's seed folder of `kind` under output/test-fuzz, emptied (not created).
fn fresh_seed_dir(kind: &str) -> PathBuf {
    let dir = root().join(format!(
        "output/test-fuzz/{kind}-seed-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The seed sweep: strip_sweep_light stopped at its budget of 6 points (1200–1279 Hz, 105
/// contact unknowns), swept once per test process.
fn sweep_seed() -> &'static Path {
    static SEED: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    SEED.get_or_init(|| {
        let dir = fresh_seed_dir("sweep");
        let options = hbcontact::pipeline::RunOptions {
            out: Some(dir.clone()),
            ..Default::default()
        };
        let p = sweep_pipeline(6);
        let result = hbcontact::sweep::run(&p, &options, &hbcontact::Silent);
        let result = result.unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(result.summary.rows.len(), 6);
        dir
    })
}

/// strip_sweep_light with `max_points`, no stability check and no plots.
fn sweep_pipeline(max_points: usize) -> Pipeline {
    let path = root().join("pipelines/strip_sweep_light.yaml");
    let sets = [
        format!("sweep.max_points={max_points}"),
        "stability.check=false".into(),
        "output.plots=false".into(),
    ];
    hbcontact::config::load_pipeline(&path, &sets).unwrap_or_else(|e| panic!("{e}"))
}

/// A value put in place of a node of sweep.json.
#[derive(Clone, Debug)]
enum JsonValue {
    Zero,
    Negative,
    Scaled(f64),
    Tiny,
    Huge,
    HugeInt,
    BigInt,
    Null,
    Bool,
    Text,
    EmptyList,
    EmptyMap,
}

impl JsonValue {
    fn json(&self, old: &serde_json::Value) -> serde_json::Value {
        use serde_json::json;
        let number = old.as_f64().unwrap_or(1.0);
        match self {
            JsonValue::Zero => json!(0),
            JsonValue::Negative => json!(-number),
            JsonValue::Scaled(f) => json!(number * f),
            JsonValue::Tiny => json!(1e-300),
            JsonValue::Huge => json!(1e300),
            JsonValue::HugeInt => json!(u64::MAX),
            JsonValue::BigInt => json!(1_000_000_000_000u64),
            JsonValue::Null => json!(null),
            JsonValue::Bool => json!(true),
            JsonValue::Text => json!("word"),
            JsonValue::EmptyList => json!([]),
            JsonValue::EmptyMap => json!({}),
        }
    }
}

fn json_value() -> impl Strategy<Value = JsonValue> {
    prop_oneof![
        Just(JsonValue::Zero),
        Just(JsonValue::Negative),
        prop_oneof![
            Just(1e-6),
            Just(0.5),
            Just(1.0 + 1e-9),
            Just(2.0),
            Just(1e6)
        ]
        .prop_map(JsonValue::Scaled),
        Just(JsonValue::Tiny),
        Just(JsonValue::Huge),
        Just(JsonValue::HugeInt),
        Just(JsonValue::BigInt),
        Just(JsonValue::Null),
        Just(JsonValue::Bool),
        Just(JsonValue::Text),
        Just(JsonValue::EmptyList),
        Just(JsonValue::EmptyMap),
    ]
}

/// One mutation of sweep.json: of its tree, then of its text.
#[derive(Clone, Debug)]
enum JsonEdit {
    Replace(Index, JsonValue),
    DeleteKey(Index),
    /// Keep a prefix of a list.
    Shorten(Index, Index),
    /// Swap two entries of a list.
    Swap(Index, Index, Index),
    Truncate(Index),
    FlipByte(Index, u8),
}

fn json_edit() -> impl Strategy<Value = JsonEdit> {
    prop_oneof![
        6 => (any::<Index>(), json_value()).prop_map(|(i, v)| JsonEdit::Replace(i, v)),
        2 => any::<Index>().prop_map(JsonEdit::DeleteKey),
        2 => (any::<Index>(), any::<Index>()).prop_map(|(i, k)| JsonEdit::Shorten(i, k)),
        1 => (any::<Index>(), any::<Index>(), any::<Index>())
            .prop_map(|(i, a, b)| JsonEdit::Swap(i, a, b)),
        1 => any::<Index>().prop_map(JsonEdit::Truncate),
        1 => (any::<Index>(), 1..=255u8).prop_map(|(i, m)| JsonEdit::FlipByte(i, m)),
    ]
}

/// The paths of sweep.json's nodes (as JSON pointers), the long multiplier, tangent and
/// trail lists (and each point of the trail) counting with their first three entries only, so
/// edits spread over every field.
fn json_paths(v: &serde_json::Value, at: String, out: &mut Vec<String>) {
    out.push(at.clone());
    let long = at.ends_with("/multipliers")
        || at.ends_with("/tangent")
        || at.ends_with("/trail")
        || at.contains("/trail/");
    match v {
        serde_json::Value::Object(m) => {
            for (k, child) in m {
                json_paths(child, format!("{at}/{k}"), out);
            }
        }
        serde_json::Value::Array(a) => {
            let n = if long { a.len().min(3) } else { a.len() };
            for (i, child) in a.iter().take(n).enumerate() {
                json_paths(child, format!("{at}/{i}"), out);
            }
        }
        _ => {}
    }
}

fn edit_json_tree(tree: &mut serde_json::Value, e: &JsonEdit) {
    let mut all = Vec::new();
    json_paths(tree, String::new(), &mut all);
    let lists: Vec<&String> = all
        .iter()
        .filter(|p| tree.pointer(p).is_some_and(|v| v.is_array()))
        .collect();
    match e {
        JsonEdit::Replace(at, v) => {
            if let Some(n) = tree.pointer_mut(&all[at.index(all.len())]) {
                *n = v.json(n);
            }
        }
        JsonEdit::DeleteKey(at) => {
            let path = all[at.index(all.len())].clone();
            let Some((parent, key)) = path.rsplit_once('/') else {
                return;
            };
            if let Some(m) = tree.pointer_mut(parent).and_then(|p| p.as_object_mut()) {
                m.remove(key);
            }
        }
        JsonEdit::Shorten(at, keep) if !lists.is_empty() => {
            let path = lists[at.index(lists.len())].clone();
            if let Some(a) = tree.pointer_mut(&path).and_then(|p| p.as_array_mut()) {
                a.truncate(keep.index(a.len() + 1));
            }
        }
        JsonEdit::Swap(at, i, j) if !lists.is_empty() => {
            let path = lists[at.index(lists.len())].clone();
            if let Some(a) = tree.pointer_mut(&path).and_then(|p| p.as_array_mut()) {
                if !a.is_empty() {
                    let (i, j) = (i.index(a.len()), j.index(a.len()));
                    a.swap(i, j);
                }
            }
        }
        _ => {}
    }
}

/// The seed's sweep.json with the edits.
fn mutate_json(seed: &str, edits: &[JsonEdit]) -> Vec<u8> {
    let mut tree: serde_json::Value = serde_json::from_str(seed).expect("the seed parses");
    for e in edits {
        edit_json_tree(&mut tree, e);
    }
    let mut bytes = serde_json::to_vec_pretty(&tree).expect("a JSON tree writes");
    for e in edits {
        match e {
            JsonEdit::Truncate(at) => bytes.truncate(at.index(bytes.len() + 1)),
            JsonEdit::FlipByte(at, mask) if !bytes.is_empty() => {
                let i = at.index(bytes.len());
                bytes[i] ^= mask;
            }
            _ => {}
        }
    }
    bytes
}

/// Copy the seed sweep's folder to `to` (replacing it) with `sweep_json` for its sweep.json.
fn sweep_case_dir(to: &Path, sweep_json: &[u8]) {
    let _ = std::fs::remove_dir_all(to);
    let status = std::process::Command::new("cp")
        .arg("-r")
        .arg(sweep_seed())
        .arg(to)
        .status()
        .expect("cp runs");
    assert!(status.success());
    std::fs::write(to.join("sweep.json"), sweep_json).expect("scratch write");
}

/// Resume the sweep in `dir` for one more point: it continues, or it fails with exit class 2
/// naming sweep.json or its saved point; no allocation above `REFUSED_BYTES`.
fn sweep_case(dir: &Path) -> std::result::Result<(), TestCaseError> {
    let options = hbcontact::pipeline::RunOptions {
        out: Some(dir.to_path_buf()),
        ..Default::default()
    };
    let p = sweep_pipeline(7);
    let (result, _) = measure(|| hbcontact::sweep::resume(&p, &options, &hbcontact::Silent));
    let error = match result {
        Ok(r) => match r.failure {
            None => return Ok(()),
            Some(e) => e,
        },
        Err(e) => e,
    };
    let text = error.to_string();
    prop_assert_eq!(error.exit_code(), 2, "bad input is exit class 2: {}", text);
    prop_assert!(
        text.contains("sweep.json") || text.contains("saved point"),
        "the error names the file or its saved point: {}",
        text
    );
    prop_assert!(
        text.chars().count() <= 5000,
        "a short error: {}",
        text.len()
    );
    Ok(())
}

proptest! {
    #![proptest_config(config())]
    /// TEST GOAL: a mutated sweep.json (numbers zeroed, negated, scaled, made tiny, huge or
    /// 10¹²; values made null, text, lists or maps; keys deleted; lists shortened or their
    /// entries swapped; truncated; bytes flipped) resumed by `sweep --resume` never panics and
    /// never allocates more than 1 GiB at once: it continues, or fails with exit class 2
    /// naming the file or its saved point.
    #[test]
    fn mutated_sweep_json_resumes_or_is_refused_naming_the_file(
        edits in prop::collection::vec(json_edit(), 1..4),
    ) {
        let seed = std::fs::read_to_string(sweep_seed().join("sweep.json")).expect("the seed reads");
        let dir = scratch("sweep-case");
        sweep_case_dir(&dir, &mutate_json(&seed, &edits));
        sweep_case(&dir)?;
    }
}

/// TEST GOAL: the three tampered sweep.json files of issue #46 are refused by
/// `hbcontact sweep --resume` with exit 2 naming the file and the field: `resume.samples`
/// = 10¹² (it drove the process to 23 GB), `resume.samples` = 0 (an index out of bounds
/// panic) and `rows = []` (exit 0 claiming the sweep reached 1800 Hz); so is each part of
/// the continuation's history a resume needs to be the uninterrupted sweep: a `largest` not
/// the trail's, a `trail` without a point per row, a point of it of another ω, a frequency the
/// reduced model learned at far outside the range, more of them than the curve can have
/// taught it, and one, or a reduced frame, resumed with `sweep.reduced_frames: false`; the
/// seed itself resumes.
#[test]
fn regression_tampered_sweep_json_fields_are_refused_naming_them() {
    let seed = std::fs::read_to_string(sweep_seed().join("sweep.json")).expect("the seed reads");
    let tree: serde_json::Value = serde_json::from_str(&seed).unwrap();
    let largest = tree["resume"]["largest"].as_f64().unwrap();
    let mut trail = tree["resume"]["trail"].clone();
    let width = trail[0].as_array().unwrap().len();
    trail[0][width - 1] = serde_json::json!(trail[1][width - 1].as_f64().unwrap());
    // (pointer, value, the field the refusal names, a `--set` of the resume)
    let factored = "sweep.reduced_frames=false";
    let cases: [(&str, serde_json::Value, &str, &str); 10] = [
        (
            "/resume/samples",
            serde_json::json!(1_000_000_000_000u64),
            "`resume.samples`",
            "",
        ),
        (
            "/resume/samples",
            serde_json::json!(0),
            "`resume.samples`",
            "",
        ),
        ("/rows", serde_json::json!([]), "`rows` is empty", ""),
        (
            "/resume/largest",
            serde_json::json!(2.0 * largest + 1.0),
            "`resume.largest`",
            "",
        ),
        ("/resume/trail", serde_json::json!([]), "`resume.trail`", ""),
        ("/resume/trail", trail, "`resume.trail[0]`", ""),
        (
            "/resume/enriched_at",
            serde_json::json!([1e300]),
            "`resume.enriched_at[0]`",
            "",
        ),
        (
            "/resume/enriched_at",
            serde_json::json!(vec![8000.0; 100_000]),
            "`resume.enriched_at` lists more frequencies (100000)",
            "",
        ),
        (
            "/resume/enriched_at",
            serde_json::json!([8000.0]),
            "reduced model (0: sweep.reduced_frames is false)",
            factored,
        ),
        (
            "/resume/reduced_frame",
            serde_json::json!(true),
            "`resume.reduced_frame`",
            factored,
        ),
    ];
    let dir = scratch("sweep-regression");
    for (pointer, value, field, set) in cases {
        let mut tree: serde_json::Value = serde_json::from_str(&seed).unwrap();
        *tree.pointer_mut(pointer).unwrap() = value;
        sweep_case_dir(&dir, &serde_json::to_vec(&tree).unwrap());
        let dir_arg = dir.to_string_lossy().to_string();
        let mut sets = vec!["sweep.max_points=7", "stability.check=false"];
        sets.extend(Some(set).filter(|s| !s.is_empty()));
        let output = std::process::Command::new(env!("CARGO_BIN_EXE_hbcontact"))
            .args([
                "sweep",
                "pipelines/strip_sweep_light.yaml",
                "--resume",
                "--quiet",
            ])
            .args(sets.iter().flat_map(|s| ["--set", s]))
            .args(["--out", &dir_arg])
            .current_dir(root())
            .output()
            .expect("hbcontact runs");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{pointer}: {stderr}");
        assert!(
            stderr.contains(&format!("{dir_arg}/sweep.json")),
            "{stderr}"
        );
        assert!(stderr.contains(field), "{stderr}");
    }
    sweep_case_dir(&dir, seed.as_bytes());
    let options = hbcontact::pipeline::RunOptions {
        out: Some(dir.clone()),
        ..Default::default()
    };
    let resumed = hbcontact::sweep::resume(&sweep_pipeline(7), &options, &hbcontact::Silent);
    assert_eq!(resumed.map(|r| r.summary.rows.len()).ok(), Some(7));
}

// ---------------------------------------------------------------------------------------------
// Study records read back: point.json and an accuracy rung's amplitudes.vtu.

/// The seed study: an accuracy study of strip_wall (coarse) over H = 2, 4, run once per test
/// process: two points, each with its point.json and amplitudes.vtu.
struct StudySeed {
    study: Study,
    out: PathBuf,
    points: Vec<hbcontact::study::plan::Point>,
}

fn study_seed() -> &'static StudySeed {
    static SEED: std::sync::OnceLock<StudySeed> = std::sync::OnceLock::new();
    SEED.get_or_init(|| {
        let dir = fresh_seed_dir("study");
        std::fs::create_dir_all(&dir).expect("seed directory");
        let path = dir.join("study.yaml");
        let text = format!(
            "name: seed\npipeline: {}\nset: {{geometry.parameters.lc: 0.005}}\naccuracy:\n  ladders:\n    - {{key: harmonic_balance.harmonics, values: [2, 4]}}\n",
            root().join("pipelines/strip_wall.yaml").display()
        );
        std::fs::write(&path, &text).expect("seed study");
        let study = parse_study(&path, &text, &[]).unwrap_or_else(|e| panic!("{e}"));
        let out = dir.join("out");
        let options = hbcontact::study::StudyOptions {
            out: Some(out.clone()),
            ..Default::default()
        };
        hbcontact::study::run(&study, &options, &hbcontact::Silent)
            .and_then(|r| r.complete())
            .unwrap_or_else(|e| panic!("{e}"));
        let points = plan(&study).unwrap_or_else(|e| panic!("{e}"));
        StudySeed { study, out, points }
    })
}

/// A copy of the seed study's point folders under `to` (replacing it), with `file` of point
/// `point` replaced by `bytes`.
fn study_case_dir(to: &Path, point: usize, file: &str, bytes: &[u8]) {
    let seed = study_seed();
    let _ = std::fs::remove_dir_all(to);
    for p in &seed.points {
        let (from, into) = (
            seed.out.join("points").join(&p.key),
            to.join("points").join(&p.key),
        );
        std::fs::create_dir_all(&into).expect("scratch directory");
        for name in ["point.json", "amplitudes.vtu"] {
            std::fs::copy(from.join(name), into.join(name)).expect("scratch copy");
        }
    }
    let path = to.join("points").join(&seed.points[point].key).join(file);
    std::fs::write(path, bytes).expect("scratch write");
}

/// The seed's `file` of point `point`.
fn study_seed_file(point: usize, file: &str) -> Vec<u8> {
    let seed = study_seed();
    std::fs::read(
        seed.out
            .join("points")
            .join(&seed.points[point].key)
            .join(file),
    )
    .expect("the seed reads")
}

/// Read the study in `out` back as a merge does (its rows from the records, then the
/// accuracy rungs and their errors from the amplitudes), holding at most `allowance` bytes:
/// either every record holds what a run writes (status ok or failed, outputs finite within
/// ±1e100) and every error is ≥ 0 (infinite against a reference value of 0) or NaN, or the
/// error is exit class 2 naming `file`
/// and the fix, and short.
fn records_case(
    out: &Path,
    file: &str,
    allowance: usize,
) -> std::result::Result<(), TestCaseError> {
    let seed = study_seed();
    let spec = seed.study.accuracy.as_ref().expect("an accuracy study");
    let (result, held) = measure(|| {
        hbcontact::study::table::rows(out, &seed.points).and_then(|rows| {
            let report = hbcontact::study::accuracy::evaluate(spec, &rows, out)?;
            let csv = hbcontact::study::table::csv(&seed.study, &rows);
            Ok((rows, report, csv))
        })
    });
    prop_assert!(held <= allowance, "reading held {} bytes", held);
    match result {
        Ok((rows, report, _)) => {
            for row in &rows {
                let r = row.record.as_ref().expect("every seed point has a record");
                prop_assert!(r.status == "ok" || r.status == "failed", "{}", r.status);
                for v in r.outputs.values().flatten() {
                    prop_assert!(v.is_finite() && v.abs() <= 1e100, "{}", v);
                }
            }
            for rung in &report.rungs {
                prop_assert!(
                    rung.errors.iter().all(|e| e.is_nan() || *e >= 0.0),
                    "{:?}",
                    rung.errors
                );
            }
            Ok(())
        }
        Err(e) => {
            let text = e.to_string();
            prop_assert_eq!(e.exit_code(), 2, "bad input is exit class 2: {}", text);
            prop_assert!(text.contains(file), "the error names {}: {}", file, text);
            prop_assert!(
                text.contains("delete the folder"),
                "the error says the fix: {}",
                text
            );
            prop_assert!(
                text.chars().count() <= 5000,
                "a short error: {}",
                text.len()
            );
            Ok(())
        }
    }
}

/// One mutation of amplitudes.vtu: a number of an XML attribute replaced (the point count,
/// a component count), or a byte-level edit as for `.msh` files.
#[derive(Clone, Debug)]
enum VtuEdit {
    Attribute(Index, String),
    Bytes(MshEdit),
}

fn vtu_edit() -> impl Strategy<Value = VtuEdit> {
    prop_oneof![
        2 => (any::<Index>(), token()).prop_map(|(i, t)| VtuEdit::Attribute(i, t)),
        3 => msh_edit().prop_map(VtuEdit::Bytes),
    ]
}

fn edit_vtu(bytes: &mut Vec<u8>, e: &VtuEdit) {
    match e {
        VtuEdit::Attribute(at, t) => {
            // The values of `Name="value"` attributes whose value is a number.
            let text = String::from_utf8_lossy(bytes).into_owned();
            let numbers: Vec<(usize, usize)> = text
                .match_indices("=\"")
                .filter_map(|(i, _)| {
                    let start = i + 2;
                    let len = text[start..].find('"')?;
                    let v = &text[start..start + len];
                    v.parse::<f64>().is_ok().then_some((start, start + len))
                })
                .collect();
            if !numbers.is_empty() {
                let (s, end) = numbers[at.index(numbers.len())];
                bytes.splice(s..end, t.bytes());
            }
        }
        VtuEdit::Bytes(b) => edit_msh(bytes, b),
    }
}

proptest! {
    #![proptest_config(config())]
    /// TEST GOAL: a mutated point.json (numbers zeroed, negated, scaled, made tiny, huge or
    /// 10¹²; values made null, text, lists or maps; keys deleted; lists shortened or swapped;
    /// truncated; bytes flipped), read back as `study --merge` reads it, never panics and holds
    /// at most 64 times its size plus 1 MiB: the table is built from records holding what a
    /// run writes, or the error is exit class 2 naming point.json and the fix.
    #[test]
    fn mutated_point_records_read_or_are_refused_naming_the_file(
        point in 0..2usize,
        edits in prop::collection::vec(json_edit(), 1..4),
    ) {
        let seed = String::from_utf8(study_seed_file(point, "point.json")).expect("text");
        let bytes = mutate_json(&seed, &edits);
        let dir = scratch("point-record-case");
        study_case_dir(&dir, point, "point.json", &bytes);
        records_case(&dir, "point.json", 64 * bytes.len() + (1 << 20))?;
    }

    /// TEST GOAL: a mutated amplitudes.vtu of an accuracy rung or of its reference (attribute
    /// numbers such as the point count replaced by 0, −1, huge values, NaN or Inf; truncated;
    /// bytes flipped, inserted or deleted) never panics (a field shorter than the nodes
    /// indexed out of bounds) and never holds more than 64 times the file's size plus 1 MiB:
    /// the errors are computed, or the error is exit class 2 naming amplitudes.vtu and the fix.
    #[test]
    fn mutated_amplitudes_read_or_are_refused_naming_the_file(
        point in 0..2usize,
        edits in prop::collection::vec(vtu_edit(), 1..4),
    ) {
        let mut bytes = study_seed_file(point, "amplitudes.vtu");
        for e in &edits {
            edit_vtu(&mut bytes, e);
        }
        let dir = scratch("amplitudes-case");
        study_case_dir(&dir, point, "amplitudes.vtu", &bytes);
        records_case(&dir, "amplitudes.vtu", 64 * bytes.len() + (1 << 20))?;
    }
}

/// TEST GOAL: the study seed reads back unmutated (its two rungs ok, the coarse one with a
/// displacement L2 error), so the mutations start from real records.
#[test]
fn study_seed_reads_back_unmutated() {
    let seed = study_seed();
    let dir = scratch("study-seed-case");
    study_case_dir(&dir, 0, "point.json", &study_seed_file(0, "point.json"));
    let rows = hbcontact::study::table::rows(&dir, &seed.points).unwrap_or_else(|e| panic!("{e}"));
    assert!(rows.iter().all(|r| r.status() == "ok"));
    let spec = seed.study.accuracy.as_ref().unwrap();
    let report =
        hbcontact::study::accuracy::evaluate(spec, &rows, &dir).unwrap_or_else(|e| panic!("{e}"));
    assert!(report.rungs[0].l2_nodes > 0, "{:?}", report.rungs[0]);
}

// ---------------------------------------------------------------------------------------------
// The bugs the fuzzing found, one named test each.

fn read_mutated(name: &str, from: &str, to: &str) -> String {
    let (_, seed) = msh_seeds().into_iter().find(|(n, _)| n == name).unwrap();
    let text = String::from_utf8_lossy(&seed).replacen(from, to, 1);
    assert!(text.as_bytes() != seed.as_slice(), "{from} is in {name}");
    let path = scratch(&format!("regression-{name}"));
    let mut bytes = seed.clone();
    // Splice in bytes, so a binary file keeps its binary part.
    let at = seed.windows(from.len()).position(|w| w == from.as_bytes());
    let at = at.unwrap();
    bytes.splice(at..at + from.len(), to.bytes());
    std::fs::write(&path, &bytes).unwrap();
    match read_msh(&path) {
        Ok(_) => panic!("{name} with {to:?} must not read"),
        Err(e) => {
            assert_eq!(e.exit_code(), 2);
            let e = e.to_string();
            assert!(e.contains(&path.display().to_string()), "{e}");
            e
        }
    }
}

/// TEST GOAL: a `$MeshFormat` line with a data size mshio has no parser for, or digits beyond
/// its integer type, is an error naming the line and the fix (mshio panicked on both:
/// `unimplemented!` and an `unwrap` of the overflowing parse).
#[test]
fn regression_a_damaged_mesh_format_line_is_an_error_not_a_panic() {
    let e = read_mutated("strip_wall_quads_binary.msh", "4.1 1 8", "4.1 1 16");
    assert!(
        e.contains("sizes of 16 bytes") && e.contains("-format msh41"),
        "{e}"
    );
    let e = read_mutated(
        "strip_wall_quads_binary.msh",
        "4.1 1 8",
        "4.1 1 18446744073709551616",
    );
    assert!(
        e.contains("$MeshFormat") && e.contains("-format msh41"),
        "{e}"
    );
    let e = read_mutated("strip_wall_order2.msh", "4.1 0 8", "4.1 99999999999 8");
    assert!(e.contains("`4.1 99999999999 8`"), "{e}");
}

/// TEST GOAL: a node with a NaN or infinite coordinate (a damaged file; the binary fuzz case
/// overwrote a coordinate with all one bits) is refused naming the node, instead of a mesh
/// whose NaN reaches the solver.
#[test]
fn regression_non_finite_node_coordinates_are_refused_naming_the_node() {
    let e = read_mutated("strip_wall_order2.msh", "0.05 0.02 0\n", "0.05 nan 0\n");
    assert!(
        e.contains("node 4 is at (0.05, NaN, 0)") && e.contains("finite"),
        "{e}"
    );
    let e = read_mutated("strip_wall_order2.msh", "0.1 0 0\n", "inf 0 0\n");
    assert!(e.contains("node 2 is at (inf, 0, 0)"), "{e}");
}

fn study_error(text: &str) -> String {
    let path = root().join("tests/data/fuzz/regression.yaml");
    match parse_study(&path, text, &[]) {
        Ok(s) => panic!("must not load: {} points", s.point_count()),
        Err(e) => {
            assert_eq!(e.exit_code(), 2);
            e.to_string()
        }
    }
}

/// TEST GOAL: a study error quotes at most an excerpt of a long value (the fuzz case: a
/// 20 000-character pipeline path echoed whole, 24 220 characters of message).
#[test]
fn regression_a_study_error_quotes_only_an_excerpt_of_a_long_value() {
    let long = "x".repeat(20_000);
    let e = study_error(&format!(
        "name: s\npipeline: {long}\nparameters: [{{key: a, values: [1]}}]\n"
    ));
    assert!(
        e.len() < 500 && e.contains("(20000 characters)") && e.contains("pipeline:"),
        "{e}"
    );
    let e = study_error(&format!(
        "name: s\npipeline: ../../../pipelines/strip_wall.yaml\nparameters: [{{key: {long}, values: []}}]\n"
    ));
    assert!(e.len() < 500 && e.contains("parameters[0]"), "{e}");
}

/// TEST GOAL: a huge `range.count`, Latin hypercube `samples` or grid product is refused
/// naming the field and the limit before any point is laid out (`count:
/// 18446744073709551615` laid out the values and took the machine's memory until the kernel
/// killed the fuzz run), and so is an absurd `threads`.
#[test]
fn regression_huge_point_counts_are_refused_before_the_points_are_laid_out() {
    let head = "name: s\npipeline: ../../../pipelines/strip_wall.yaml\n";
    let e = study_error(&format!(
        "{head}parameters: [{{key: geometry.parameters.gap, range: {{from: 1, to: 2, count: 18446744073709551615}}}}]\n"
    ));
    assert!(
        e.contains("parameters[0] (geometry.parameters.gap).range.count = 18446744073709551615")
            && e.contains("100000"),
        "{e}"
    );
    let e = study_error(&format!(
        "{head}design: {{latin_hypercube: {{samples: 1000000000}}}}\nparameters: [{{key: a, range: {{from: 1, to: 2}}}}]\n"
    ));
    assert!(
        e.contains("design.latin_hypercube.samples = 1000000000"),
        "{e}"
    );
    let e = study_error(&format!(
        "{head}parameters:\n  - {{key: a, range: {{from: 1, to: 2, count: 1000}}}}\n  - {{key: b, range: {{from: 1, to: 2, count: 1000}}}}\n"
    ));
    assert!(
        e.contains("1000000 points") && e.contains("split it"),
        "{e}"
    );
    let e = study_error(&format!(
        "{head}threads: 100000000\nparameters: [{{key: a, values: [1]}}]\n"
    ));
    assert!(e.contains("threads = 100000000"), "{e}");
}
