//! The README's tour and the tutorials (docs/tutorials.md) are true as written: every command
//! they show runs, and prints what they say it prints.
//!
//! Conventions of README.md (and of any Markdown file `run_console_blocks` is given):
//! - ```` ```console ```` blocks are run. A line starting with `$ ` is a command, the lines
//!   after it (up to the next `$ ` line) are output it must print: each, in order, a line of
//!   its stdout or stderr (whitespace runs count as one space). An output line may leave out
//!   lines the command prints, never change one.
//! - Numbers in an output line are compared to the digits the README prints: 8.0836e-8
//!   matches a printed value within half a unit of its last digit. A token `…` stands for any
//!   one token (wall times, peak memories, thread counts, round-off).
//! - Commands are `hbcontact …` or `./target/release/hbcontact …`, run with this build's
//!   binary in the repository root and exiting 0. Arguments are split at spaces (no quoting).
//!   An argument under `output/tour/` is written into a scratch folder instead (and the
//!   scratch folder reads back as `output/tour/` in the output), so the test leaves a user's
//!   tour alone.
//! - ```` ```sh ```` blocks (`make run`, `make test`) are shown, not run.
//! - A ```` ```yaml ```` block is an excerpt of the last `pipelines/….yaml` the text before it
//!   names: its lines, in order, are lines of that file.

mod common;

use std::path::Path;
use std::process::Command;

/// Where `output/tour/` goes while the README's commands run (relative to the repository
/// root); each document has its own, so their tests may run side by side.
const SCRATCH: &str = "output/test-runs/readme";
/// The tutorials' scratch folder.
const TUTORIALS_SCRATCH: &str = "output/test-runs/tutorials";
const TOUR: &str = "output/tour/";

/// A fenced block: its info string, its lines, and the Markdown before it.
struct Block {
    info: String,
    lines: Vec<String>,
    before: String,
}

/// The fenced blocks of `markdown`, in order; an unclosed fence is an error.
fn fenced_blocks(markdown: &str) -> Result<Vec<Block>, String> {
    let mut blocks = Vec::new();
    let mut open: Option<Block> = None;
    let mut prose = String::new();
    for (n, line) in markdown.lines().enumerate() {
        let fence = line.trim_start().strip_prefix("```");
        match (&mut open, fence) {
            (None, Some(info)) => {
                open = Some(Block {
                    info: info.trim().to_string(),
                    lines: Vec::new(),
                    before: std::mem::take(&mut prose),
                });
            }
            (Some(_), Some(rest)) if rest.trim().is_empty() => {
                blocks.extend(open.take());
            }
            (Some(_), Some(_)) => return Err(format!("line {}: a fence inside a block", n + 1)),
            (Some(b), None) => b.lines.push(line.to_string()),
            (None, None) => {
                prose.push_str(line);
                prose.push('\n');
            }
        }
    }
    match open {
        Some(b) => Err(format!("a ```{} block is not closed", b.info)),
        None => Ok(blocks),
    }
}

/// A command of a console block and the output lines it must print.
#[derive(Debug, PartialEq)]
struct Step {
    command: String,
    expected: Vec<String>,
}

fn steps(block: &Block) -> Result<Vec<Step>, String> {
    let mut steps: Vec<Step> = Vec::new();
    for line in &block.lines {
        if let Some(command) = line.strip_prefix("$ ") {
            steps.push(Step {
                command: command.trim().to_string(),
                expected: Vec::new(),
            });
        } else if let Some(step) = steps.last_mut() {
            if !line.trim().is_empty() {
                step.expected.push(line.to_string());
            }
        } else {
            return Err(format!("console output before any command: {line:?}"));
        }
    }
    Ok(steps)
}

/// A piece of a token: text, or a number with the size of a unit in its last printed digit.
#[derive(Debug, PartialEq)]
enum Piece {
    Text(String),
    Number { value: f64, unit: f64 },
}

/// The digits of a number starting at `chars[i]`: (end, value, unit of the last digit).
fn number_at(chars: &[char], i: usize) -> Option<(usize, f64, f64)> {
    let digit = |j: usize| chars.get(j).is_some_and(|c| c.is_ascii_digit());
    let mut j = i;
    if matches!(chars.get(j), Some('+' | '-')) {
        j += 1;
    }
    if !digit(j) {
        return None;
    }
    while digit(j) {
        j += 1;
    }
    let mut decimals = 0i32;
    if chars.get(j) == Some(&'.') && digit(j + 1) {
        j += 1;
        while digit(j) {
            j += 1;
            decimals += 1;
        }
    }
    let mantissa_end = j;
    let mut exponent = 0i32;
    if matches!(chars.get(j), Some('e' | 'E')) {
        let k = j + usize::from(matches!(chars.get(j + 1), Some('+' | '-')));
        if digit(k + 1) {
            let mut end = k + 1;
            while digit(end) {
                end += 1;
            }
            exponent = chars[j + 1..end].iter().collect::<String>().parse().ok()?;
            j = end;
        }
    }
    let mantissa: f64 = chars[i..mantissa_end]
        .iter()
        .collect::<String>()
        .parse()
        .ok()?;
    let scale = 10f64.powi(exponent);
    Some((j, mantissa * scale, 10f64.powi(-decimals) * scale))
}

/// `token` as text and numbers. A sign starts a number only where no letter or digit precedes
/// it (`-49.93%` is a number, `half-power` is text).
fn pieces(token: &str) -> Vec<Piece> {
    let chars: Vec<char> = token.chars().collect();
    let mut out = Vec::new();
    let mut text = String::new();
    let mut i = 0;
    while i < chars.len() {
        let after_word = i > 0 && chars[i - 1].is_alphanumeric();
        let starts = chars[i].is_ascii_digit() || (!after_word && matches!(chars[i], '+' | '-'));
        if let Some((end, value, unit)) = starts.then(|| number_at(&chars, i)).flatten() {
            if !text.is_empty() {
                out.push(Piece::Text(std::mem::take(&mut text)));
            }
            out.push(Piece::Number { value, unit });
            i = end;
        } else {
            text.push(chars[i]);
            i += 1;
        }
    }
    if !text.is_empty() {
        out.push(Piece::Text(text));
    }
    out
}

/// Whether the printed `actual` token is the README's `expected` one at the README's digits.
fn token_matches(expected: &str, actual: &str) -> bool {
    if expected == "…" {
        return true;
    }
    let (e, a) = (pieces(expected), pieces(actual));
    e.len() == a.len()
        && e.iter().zip(&a).all(|pair| match pair {
            (Piece::Text(x), Piece::Text(y)) => x == y,
            (Piece::Number { value: r, unit }, Piece::Number { value: v, .. }) => {
                (v - r).abs() <= 0.5 * unit * (1.0 + 1e-9)
            }
            _ => false,
        })
}

fn line_matches(expected: &str, actual: &str) -> bool {
    let e: Vec<&str> = expected.split_whitespace().collect();
    let a: Vec<&str> = actual.split_whitespace().collect();
    e.len() == a.len() && e.iter().zip(&a).all(|(x, y)| token_matches(x, y))
}

/// The expected lines that `stdout` and `stderr` do not print in order (each stream read
/// forward on its own), as messages.
fn unmatched(expected: &[String], stdout: &str, stderr: &str) -> Vec<String> {
    let streams: [Vec<&str>; 2] = [stdout.lines().collect(), stderr.lines().collect()];
    let mut at = [0usize; 2];
    let mut missing = Vec::new();
    for line in expected {
        let found = (0..2).find_map(|s| {
            streams[s][at[s]..]
                .iter()
                .position(|a| line_matches(line, a))
                .map(|p| (s, at[s] + p + 1))
        });
        match found {
            Some((s, next)) => at[s] = next,
            None => missing.push(line.clone()),
        }
    }
    missing
}

/// The command line's arguments after the program, with `output/tour/` moved to the scratch
/// folder `scratch`.
fn arguments(command: &str, scratch: &str) -> Result<Vec<String>, String> {
    if command.contains(['"', '\'', '|', '>', '<', ';', '&', '$']) {
        return Err(format!(
            "`{command}`: no quoting, pipes or redirections, please"
        ));
    }
    let mut words = command.split_whitespace();
    let program = words.next().unwrap_or("");
    if program != "hbcontact" && program != "./target/release/hbcontact" {
        return Err(format!("`{command}` does not run hbcontact"));
    }
    Ok(words
        .map(|w| match w.strip_prefix(TOUR) {
            Some(rest) => format!("{scratch}/{rest}"),
            None => w.to_string(),
        })
        .collect())
}

/// Runs `step` and returns what is wrong with its output (empty: nothing).
fn run_step(step: &Step, scratch: &str) -> Result<Vec<String>, String> {
    let args = arguments(&step.command, scratch)?;
    let out = Command::new(env!("CARGO_BIN_EXE_hbcontact"))
        .args(&args)
        .current_dir(common::root())
        .output()
        .map_err(|e| format!("`{}` did not start: {e}", step.command))?;
    let back = |s: &[u8]| String::from_utf8_lossy(s).replace(&format!("{scratch}/"), TOUR);
    let (stdout, stderr) = (back(&out.stdout), back(&out.stderr));
    if !out.status.success() {
        return Err(format!(
            "`{}` exited with {:?}:\n{stderr}",
            step.command,
            out.status.code()
        ));
    }
    let missing = unmatched(&step.expected, &stdout, &stderr);
    Ok(missing
        .into_iter()
        .map(|m| format!("`{}` did not print {m:?}\nstdout:\n{stdout}", step.command))
        .collect())
}

/// The last `pipelines/….yaml` named in `text`.
fn last_pipeline_named(text: &str) -> Option<&str> {
    let at = text.rfind("`pipelines/")?;
    let rest = &text[at + 1..];
    let end = rest.find('`')?;
    rest[..end].ends_with(".yaml").then(|| &rest[..end])
}

/// What is wrong with the YAML excerpt `block` of the pipeline its text names.
fn excerpt_problems(block: &Block, root: &Path) -> Vec<String> {
    let Some(name) = last_pipeline_named(&block.before) else {
        return vec!["a yaml block whose text names no `pipelines/….yaml`".into()];
    };
    let file = std::fs::read_to_string(root.join(name)).unwrap_or_default();
    let mut lines = file.lines();
    block
        .lines
        .iter()
        .filter(|l| !lines.any(|f| f == l.as_str()))
        .map(|l| format!("{name} has no line {l:?} (in the README's order)"))
        .collect()
}

/// Runs every console block of the Markdown file `doc`, its `output/tour/` in `scratch`;
/// returns the commands run and the problems found.
fn run_console_blocks(doc: &str, scratch: &str) -> (usize, Vec<String>) {
    let root = common::root();
    let text = std::fs::read_to_string(root.join(doc)).expect("the document reads");
    let blocks = match fenced_blocks(&text) {
        Ok(b) => b,
        Err(e) => return (0, vec![format!("{doc}: {e}")]),
    };
    let _ = std::fs::remove_dir_all(root.join(scratch));
    let (mut ran, mut problems) = (0, Vec::new());
    for block in &blocks {
        match block.info.as_str() {
            "console" => match steps(block) {
                Ok(steps) => {
                    for step in &steps {
                        ran += 1;
                        match run_step(step, scratch) {
                            Ok(p) => problems.extend(p),
                            Err(e) => problems.push(e),
                        }
                    }
                }
                Err(e) => problems.push(format!("{doc}: {e}")),
            },
            "yaml" => problems.extend(excerpt_problems(block, &root)),
            "sh" | "text" | "" => {}
            other => problems.push(format!(
                "{doc}: a ```{other} block (console, sh, yaml or text)"
            )),
        }
    }
    (ran, problems)
}

#[test]
fn every_readme_command_runs_and_prints_the_numbers_the_readme_shows() {
    let (ran, problems) = run_console_blocks("README.md", SCRATCH);
    assert!(ran >= 8, "only {ran} commands found: is the parser broken?");
    assert!(problems.is_empty(), "{}", problems.join("\n\n"));
}

/// TEST GOAL: the tutorials (docs/tutorials.md) are true as written: every command runs and
/// prints what the tutorial shows, under the README's conventions.
#[test]
fn every_tutorial_command_runs_and_prints_what_the_tutorial_shows() {
    let (ran, problems) = run_console_blocks("docs/tutorials.md", TUTORIALS_SCRATCH);
    assert!(
        ran >= 10,
        "only {ran} commands found: is the parser broken?"
    );
    assert!(problems.is_empty(), "{}", problems.join("\n\n"));
}

#[test]
fn the_readme_opens_with_the_two_make_commands() {
    let text = std::fs::read_to_string(common::root().join("README.md")).unwrap();
    let first = &fenced_blocks(&text).unwrap()[0];
    assert_eq!(first.info, "sh");
    assert!(first.lines[0].starts_with("make run "), "{:?}", first.lines);
    assert!(
        first.lines[1].starts_with("make test "),
        "{:?}",
        first.lines
    );
    let lines = text.lines().count();
    assert!(
        lines <= 260,
        "the README has {lines} lines: move detail into docs/"
    );
}

#[test]
fn numbers_match_at_the_printed_digits_and_an_ellipsis_matches_any_token() {
    assert!(line_matches("peak 3.1844e3 N", "peak   3.18441e3 N"));
    assert!(line_matches("(-26.57%, ζ", "(-26.5749%, ζ"));
    assert!(!line_matches("peak 3.1844e3 N", "peak 3.1846e3 N"));
    assert!(!line_matches("peak 3.1844e3 N", "peak 3.1844e4 N"));
    assert!(!line_matches("-1.531e-3", "+1.531e-3"));
    assert!(line_matches("wall time: … s", "wall time: 0.695 s"));
    assert!(!line_matches("wall time: … s", "wall time: 0.695 s extra"));
    assert!(line_matches("half-power 0–20 H/2", "half-power 0–20 H/2"));
    assert!(!line_matches("fold 1", "folds 1"));
}

#[test]
fn tokens_split_into_text_and_numbers_with_their_last_digits_unit() {
    let number = |value: f64, unit: f64| Piece::Number { value, unit };
    let text = |t: &str| Piece::Text(t.into());
    assert_eq!(
        pieces("(-49.93%,"),
        [text("("), number(-49.93, 0.01), text("%,")]
    );
    let p = pieces("8.0836e-8");
    let Piece::Number { value, unit } = p[0] else {
        panic!("{p:?}")
    };
    assert!((value - 8.0836e-8).abs() < 1e-20 && (unit - 1e-12).abs() < 1e-24);
    assert_eq!(pieces("half-power"), [text("half-power")]);
    assert_eq!(pieces("H/2"), [text("H/"), number(2.0, 1.0)]);
}

#[test]
fn console_blocks_pair_commands_with_the_output_after_them() {
    let md = "text\n```console\n$ hbcontact a\none\n\ntwo\n$ hbcontact b\n```\n";
    let blocks = fenced_blocks(md).unwrap();
    assert_eq!(blocks[0].before, "text\n");
    let steps = steps(&blocks[0]).unwrap();
    assert_eq!(
        steps,
        [
            Step {
                command: "hbcontact a".into(),
                expected: vec!["one".into(), "two".into()]
            },
            Step {
                command: "hbcontact b".into(),
                expected: vec![]
            }
        ]
    );
    assert!(fenced_blocks("```sh\nmake\n").is_err());
}

#[test]
fn expected_lines_are_found_in_order_in_either_stream() {
    let e = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    assert!(unmatched(&e(&["a 1", "c 3", "w"]), "a 1\nb 2\nc 3\n", "w\n").is_empty());
    assert_eq!(unmatched(&e(&["c 3", "a 1"]), "a 1\nc 3\n", ""), ["a 1"]);
}

#[test]
fn tour_outputs_go_to_the_scratch_folder_and_other_programs_are_refused() {
    assert_eq!(
        arguments("hbcontact run p.yaml --out output/tour/x", SCRATCH).unwrap(),
        ["run", "p.yaml", "--out", "output/test-runs/readme/x"]
    );
    assert!(arguments("rm -rf output", SCRATCH).is_err());
    assert!(arguments("hbcontact run p.yaml > log", SCRATCH).is_err());
}
