//! The examples in README.md and docs/ cannot go stale: every TOML block is parsed as a
//! configuration file, and every `slamesh` command in a shell block (`slamesh ...` or `cargo
//! run --release --bin slamesh -- ...`) is parsed by the command's own argument parser; every
//! other shell line must name something that exists here (an example, a tool, a file) or be a
//! known program. The commands at the top of the README run in CI itself (`.ci/run`).

use slamesh::run::config_file;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The markdown files with examples.
fn documents() -> Vec<PathBuf> {
    let mut docs = vec![root().join("README.md")];
    for e in std::fs::read_dir(root().join("docs")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "md") {
            docs.push(p);
        }
    }
    docs.sort();
    docs
}

/// The fenced blocks of `text` in language `lang`, each with its first line's number.
fn blocks(text: &str, lang: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut open: Option<(usize, String)> = None;
    for (i, line) in text.lines().enumerate() {
        let fence = line.trim_start().strip_prefix("```");
        match (&mut open, fence) {
            (None, Some(tag)) => {
                open = Some((
                    i + 2,
                    if tag.trim() == lang {
                        String::new()
                    } else {
                        "\0".into()
                    },
                ))
            }
            (Some(_), Some(_)) => {
                let (at, body) = open.take().unwrap();
                if body != "\0" {
                    out.push((at, body));
                }
            }
            (Some((_, body)), None) if body != "\0" => {
                body.push_str(line);
                body.push('\n');
            }
            _ => {}
        }
    }
    out
}

/// The shell lines of a block: comments cut, `\` continuations joined, a `for V in A ...; do
/// CMD; done` loop turned into CMD with V as A.
fn shell_lines(block: &str) -> Vec<String> {
    let mut lines = Vec::new();
    let mut pending = String::new();
    for raw in block.lines() {
        let line = match raw.find(" #") {
            Some(at) => &raw[..at],
            None if raw.trim_start().starts_with('#') => "",
            None => raw,
        };
        let line = line.trim_end();
        if let Some(head) = line.strip_suffix('\\') {
            pending.push_str(head);
            pending.push(' ');
            continue;
        }
        pending.push_str(line);
        let whole = std::mem::take(&mut pending);
        if !whole.trim().is_empty() {
            lines.push(unloop(whole.trim()));
        }
    }
    lines
}

fn unloop(line: &str) -> String {
    let Some(rest) = line.strip_prefix("for ") else {
        return line.to_string();
    };
    let (var, rest) = rest.split_once(" in ").unwrap();
    let (values, rest) = rest.split_once("; do ").unwrap();
    let first = values.split_whitespace().next().unwrap();
    let body = rest.trim_end_matches("done").trim().trim_end_matches(';');
    body.replace(&format!("${var}"), first)
}

/// A placeholder's stand-in: `N` and `K` a count, `S` a seed, `P` a preset, `0X` a sequence;
/// `[...]` optional parts dropped; `a | b` alternatives: the first.
fn filled(args: &str) -> Vec<String> {
    let mut text = String::new();
    let mut depth = 0;
    for c in args.chars() {
        match c {
            '[' => depth += 1,
            ']' => depth -= 1,
            _ if depth == 0 => text.push(c),
            _ => {}
        }
    }
    text.split_whitespace()
        .map(|w| match w {
            "N" | "K" => "2".to_string(),
            "S" => "1".to_string(),
            "P" => "default".to_string(),
            _ => w.replace("0X", "00").replace("outX", "out00"),
        })
        .collect()
}

/// What a shell line runs, past `cd DIR &&` and `VAR=value` prefixes.
fn command_of(line: &str) -> &str {
    let mut rest = line.trim();
    loop {
        if let Some((cd, after)) = rest
            .split_once("&&")
            .filter(|(a, _)| a.trim_start().starts_with("cd "))
        {
            let _ = cd;
            rest = after.trim();
            continue;
        }
        match rest.split_once(' ') {
            Some((first, after)) if first.contains('=') && !first.starts_with('-') => {
                rest = after.trim()
            }
            _ => return rest,
        }
    }
}

/// Programs the docs may run that are not this project's.
const OTHER_PROGRAMS: [&str; 9] = [
    "cargo", "pip", "ssh", "cd", "printf", "python3", "git", "time", "bash",
];

#[test]
fn every_toml_block_parses_as_a_configuration() {
    let mut checked = 0;
    for doc in documents() {
        let text = std::fs::read_to_string(&doc).unwrap();
        for (line, block) in blocks(&text, "toml") {
            if let Err(e) = config_file::parse(&block) {
                panic!("{}:{line}: {e}\n{block}", doc.display());
            }
            checked += 1;
        }
    }
    assert!(checked >= 1, "no TOML block found");
}

#[test]
fn every_slamesh_command_in_the_docs_parses() {
    let mut parsed = 0;
    let mut bad = Vec::new();
    for doc in documents() {
        let text = std::fs::read_to_string(&doc).unwrap();
        for (at, block) in blocks(&text, "sh") {
            for line in shell_lines(&block) {
                let cmd = command_of(&line);
                let args = if let Some(a) = cmd.strip_prefix("slamesh ") {
                    a
                } else if let Some((_, a)) = cmd.split_once("--bin slamesh -- ") {
                    a
                } else {
                    check_other(cmd, &mut bad, &doc, at);
                    continue;
                };
                parsed += 1;
                if let Err(e) = slamesh::cli::parse_args(filled(args)) {
                    let first = e.lines().next().unwrap_or_default().to_string();
                    bad.push(format!("{}:{at}: slamesh {args}: {first}", doc.display()));
                }
            }
        }
    }
    assert!(parsed >= 10, "only {parsed} slamesh commands found");
    assert!(bad.is_empty(), "stale examples:\n{}", bad.join("\n"));
}

/// A line that is not a `slamesh` command names an example, a tool or a known program.
fn check_other(cmd: &str, bad: &mut Vec<String>, doc: &Path, at: usize) {
    let first = cmd.split_whitespace().next().unwrap_or_default();
    if let Some((_, rest)) = cmd.split_once("--example ") {
        let name = rest.split_whitespace().next().unwrap_or_default();
        let in_examples = root().join("examples").join(format!("{name}.rs")).is_file();
        if !in_examples {
            bad.push(format!("{}:{at}: no example {name}", doc.display()));
        }
    } else if first.starts_with("tools/") || first.starts_with("../../tools/") {
        if !root().join(first.trim_start_matches("../../")).is_file() {
            bad.push(format!("{}:{at}: no tool {first}", doc.display()));
        }
    } else if first == "python3" {
        let script = cmd.split_whitespace().nth(1).unwrap_or_default();
        let script = script.trim_start_matches("../../");
        if script.ends_with(".py") && !root().join(script).is_file() {
            bad.push(format!("{}:{at}: no script {script}", doc.display()));
        }
    } else if !OTHER_PROGRAMS.contains(&first) {
        bad.push(format!(
            "{}:{at}: unknown program in `{cmd}`",
            doc.display()
        ));
    }
}

#[test]
fn the_block_reader_finds_commands_through_loops_placeholders_and_prefixes() {
    let md = "text\n```sh\nslamesh run a --out b   # c\nfor m in off on; do slamesh run x --loop-closure $m; done\n```\n```toml\npreset = \"kitti\"\n```\n";
    let sh = blocks(md, "sh");
    assert_eq!(sh.len(), 1);
    let lines = shell_lines(&sh[0].1);
    assert_eq!(
        lines,
        ["slamesh run a --out b", "slamesh run x --loop-closure off"]
    );
    assert_eq!(blocks(md, "toml")[0].1, "preset = \"kitti\"\n");
    assert_eq!(
        filled("bench d --threads N [--seed S] 0X"),
        ["bench", "d", "--threads", "2", "00"]
    );
    assert_eq!(command_of("cd x && SLAMESH_DATA=y cargo run"), "cargo run");
    // A stale flag is caught.
    assert!(slamesh::cli::parse_args(["run", "a", "--out", "b", "--no-such-flag"]).is_err());
    assert!(config_file::parse("[window]\nevict_after = 100\n").is_err());
}
