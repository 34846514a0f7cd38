//! The layout rules the code keeps (docs/design.md §2), checked on the sources:
//! - the core's modules import each other without a loop;
//! - no source file holds more than 600 lines before its tests;
//! - every section of docs/design.md that a source cites exists there;
//! - the std crate's rooms import only from rooms below their own ([`ROOMS`]);
//! - a run reads as short named stages: no function in `run/` over 80 lines, `Run::step` at
//!   most 60.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

const MAX_LINES_BEFORE_TESTS: usize = 600;
/// The folders of Rust sources the rules cover.
const SOURCE_DIRS: [&str; 5] = [
    "core/src",
    "sim/src",
    "std-adapters/src",
    "tests",
    "examples",
];
/// How code cites the design notes (split so that this file does not cite).
const CITE: &str = concat!("design.md ", "§");

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Every `.rs` file below `dir`.
fn sources(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                if p.file_name().is_some_and(|n| n != "target") {
                    stack.push(p);
                }
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// The code of a file before its unit tests, without comment lines.
fn code_before_tests(text: &str) -> Vec<&str> {
    text.lines()
        .take_while(|l| l.trim() != "#[cfg(test)]")
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect()
}

/// The modules of `crate::name` paths in `lines` (first segment only).
fn imported_modules(lines: &[&str]) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    for l in lines {
        for (at, _) in l.match_indices("crate::") {
            let rest = &l[at + "crate::".len()..];
            let name: String = rest
                .chars()
                .take_while(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || *c == '_')
                .collect();
            if !name.is_empty() {
                out.insert(name);
            }
        }
    }
    out
}

/// A module that reaches itself through the import graph, with the loop's path.
fn find_loop(graph: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        m: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(i) = path.iter().position(|p| p == m) {
            let mut cycle = path[i..].to_vec();
            cycle.push(m.to_string());
            return Some(cycle);
        }
        if done.contains(m) {
            return None;
        }
        path.push(m.to_string());
        for next in graph.get(m).into_iter().flatten() {
            if let Some(c) = visit(next, graph, path, done) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(m.to_string());
        None
    }
    let mut done = BTreeSet::new();
    graph
        .keys()
        .find_map(|m| visit(m, graph, &mut Vec::new(), &mut done))
}

#[test]
fn the_core_modules_import_each_other_without_a_loop() {
    let dir = root().join("core/src");
    let files = sources(&dir);
    let modules: BTreeSet<String> = files
        .iter()
        .filter_map(|p| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
        .filter(|m| m != "lib")
        .collect();
    assert!(modules.len() > 15, "found only {modules:?} in {dir:?}");
    let mut graph = BTreeMap::new();
    for p in &files {
        let m = p.file_stem().unwrap().to_string_lossy().into_owned();
        let text = std::fs::read_to_string(p).unwrap();
        let uses: BTreeSet<String> = imported_modules(&code_before_tests(&text))
            .into_iter()
            .filter(|u| modules.contains(u) && *u != m)
            .collect();
        graph.insert(m, uses);
    }
    assert_eq!(
        find_loop(&graph),
        None,
        "an import loop among the core's modules"
    );
}

#[test]
fn the_loop_finder_finds_a_planted_loop() {
    let g = |edges: &[(&str, &str)]| {
        let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for (a, b) in edges {
            g.entry(a.to_string()).or_default().insert(b.to_string());
            g.entry(b.to_string()).or_default();
        }
        g
    };
    assert_eq!(find_loop(&g(&[("a", "b"), ("b", "c"), ("a", "c")])), None);
    let found = find_loop(&g(&[("a", "b"), ("b", "c"), ("c", "a"), ("d", "a")])).unwrap();
    assert_eq!(found.first(), found.last());
    assert_eq!(found.len(), 4);
    let lines = [
        "use crate::gp::{self, GpScratch};",
        "// crate::map in a comment",
    ];
    assert_eq!(
        imported_modules(&code_before_tests(&lines.join("\n"))),
        BTreeSet::from(["gp".to_string()])
    );
}

#[test]
fn no_source_file_holds_more_than_600_lines_before_its_tests() {
    let root = root();
    let mut long = Vec::new();
    let mut seen = 0;
    for dir in SOURCE_DIRS {
        for p in sources(&root.join(dir)) {
            seen += 1;
            let text = std::fs::read_to_string(&p).unwrap();
            let n = text
                .lines()
                .take_while(|l| l.trim() != "#[cfg(test)]")
                .count();
            if n > MAX_LINES_BEFORE_TESTS {
                long.push(format!("{}: {n} lines", p.display()));
            }
        }
    }
    assert!(seen > 60, "found only {seen} source files");
    assert!(long.is_empty(), "split by concept: {long:?}");
}

#[test]
fn every_cited_design_section_exists() {
    let root = root();
    let design = std::fs::read_to_string(root.join("docs/design.md")).unwrap();
    let sections: BTreeSet<String> = design
        .lines()
        .filter(|l| l.starts_with('#'))
        .filter_map(|l| l.trim_start_matches('#').split_whitespace().next())
        .map(|n| n.trim_end_matches('.').to_string())
        .collect();
    let mut cited = 0;
    let mut missing = Vec::new();
    for dir in SOURCE_DIRS {
        for p in sources(&root.join(dir)) {
            let text = std::fs::read_to_string(&p).unwrap();
            for (at, _) in text.match_indices(CITE) {
                let n: String = text[at + CITE.len()..]
                    .chars()
                    .take_while(|c| c.is_ascii_digit() || *c == '.')
                    .collect();
                let n = n.trim_end_matches('.').to_string();
                cited += 1;
                if !sections.contains(&n) {
                    missing.push(format!("{}: §{n}", p.display()));
                }
            }
        }
    }
    assert!(cited > 20, "found only {cited} citations");
    assert!(
        missing.is_empty(),
        "cited but not in docs/design.md: {missing:?}"
    );
}

/// The std crate's rooms, lowest first: a module may import only from rooms below its own
/// (docs/design.md §2). A new top-level module must be placed here.
const ROOMS: [(&str, u8); 21] = [
    ("io", 0),
    ("mutants", 0),
    ("parallel", 0),
    ("formats", 1),
    ("sources", 2),
    ("outputs", 2),
    ("stage", 3),
    ("eval", 4),
    ("loop_closure", 4),
    ("localize", 4),
    ("navmap", 4),
    ("inertial", 4),
    ("dynamic", 4),
    ("run", 5),
    ("view", 6),
    ("ros2", 6),
    ("merge", 6),
    ("demo", 7),
    ("cli", 8),
    // Test helpers, and the crate root's macros: used anywhere.
    ("test_support", 9),
    ("lib", 9),
];

/// The room of `module`, if it is one.
fn room(module: &str) -> Option<u8> {
    ROOMS.iter().find(|(m, _)| *m == module).map(|(_, r)| *r)
}

/// `(file, its room, the rooms it imports)` for every source of the std crate.
fn std_imports() -> Vec<(PathBuf, String, BTreeSet<String>)> {
    let src = root().join("std-adapters/src");
    sources(&src)
        .into_iter()
        .map(|p| {
            let rel = p.strip_prefix(&src).unwrap();
            let first = rel
                .components()
                .next()
                .unwrap()
                .as_os_str()
                .to_string_lossy();
            let own = first.trim_end_matches(".rs").to_string();
            let text = std::fs::read_to_string(&p).unwrap();
            let uses = imported_modules(&code_before_tests(&text));
            (p, own, uses)
        })
        .collect()
}

#[test]
fn no_import_runs_up_from_a_lower_room_to_a_higher_one() {
    let mut up = Vec::new();
    let mut unplaced = BTreeSet::new();
    let files = std_imports();
    assert!(files.len() > 60, "found only {} files", files.len());
    for (p, own, uses) in &files {
        if own == "main" {
            continue;
        }
        let Some(mine) = room(own) else {
            unplaced.insert(own.clone());
            continue;
        };
        for u in uses.iter().filter(|u| *u != own) {
            match room(u) {
                Some(theirs) if theirs >= mine && mine < 9 => {
                    up.push(format!("{} ({own}) imports {u}", p.display()))
                }
                _ => {}
            }
        }
    }
    assert!(
        unplaced.is_empty(),
        "top-level modules with no room in ROOMS: {unplaced:?}"
    );
    assert!(
        up.is_empty(),
        "imports that run up or sideways:\n{}",
        up.join("\n")
    );
}

/// The rooms of the capabilities a run holds as stages (`crate::stage`), which `run/` reaches
/// only through the one list that wires them (`run/wiring.rs`).
const CAPABILITIES: [&str; 5] = ["inertial", "navmap", "dynamic", "loop_closure", "localize"];

/// What `run/` still names of them outside the wiring, file by file (issue 81): their options
/// (`RunOptions`'s fields and the `[imu]` block of the configuration file), loop closure's
/// share of a memory cap, and the paged map the start opens (its frames and path come from
/// the pager's file). The list only shrinks: a file that names no capability any more is
/// taken off it, and a new file or name fails the test.
const STILL_NAMED_IN_RUN: [(&str, &[&str]); 4] = [
    ("config_file.rs", &["inertial"]),
    ("options.rs", &["inertial", "navmap", "loop_closure"]),
    ("setup.rs", &["localize"]),
    ("window.rs", &["loop_closure"]),
];

#[test]
fn run_names_its_capabilities_only_in_the_list_that_wires_them() {
    let run = root().join("std-adapters/src/run");
    let mut named = Vec::new();
    for (p, own, uses) in std_imports() {
        let file = p.strip_prefix(&run).map(|f| f.display().to_string());
        let Ok(file) = file else { continue };
        if own != "run" || file == "wiring.rs" {
            continue;
        }
        let theirs: Vec<&str> = CAPABILITIES
            .into_iter()
            .filter(|c| uses.contains(*c))
            .collect();
        if !theirs.is_empty() {
            named.push((file, theirs));
        }
    }
    named.sort();
    let still: Vec<(String, Vec<&str>)> = STILL_NAMED_IN_RUN
        .iter()
        .map(|(f, c)| (f.to_string(), c.to_vec()))
        .collect();
    assert_eq!(
        named, still,
        "run/ files that import a capability's room other than run/wiring.rs (update \
         STILL_NAMED_IN_RUN only to take names off it)"
    );
}

#[test]
fn the_room_check_catches_a_planted_upward_import() {
    let lines = ["use crate::run::Run;", "use crate::formats::ply;"];
    let uses = imported_modules(&code_before_tests(&lines.join("\n")));
    let upward: Vec<&String> = uses
        .iter()
        .filter(|u| room(u).unwrap() >= room("sources").unwrap())
        .collect();
    assert_eq!(upward, [&"run".to_string()]);
}

/// `(name, lines)` of each function in `text` (rustfmt's layout: the closing brace at the
/// indentation of the `fn` line).
fn functions(text: &str) -> Vec<(String, usize)> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    for (i, l) in lines.iter().enumerate() {
        let t = l.trim_start();
        let indent = &l[..l.len() - t.len()];
        let t = t
            .trim_start_matches("pub(crate) ")
            .trim_start_matches("pub(super) ")
            .trim_start_matches("pub ")
            .trim_start_matches("const ");
        let Some(rest) = t.strip_prefix("fn ") else {
            continue;
        };
        let name: String = rest
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        let close = format!("{indent}}}");
        let end = (i..lines.len())
            .find(|&j| lines[j] == close || (j == i && l.trim_end().ends_with('}')))
            .unwrap_or(i);
        out.push((name, end - i + 1));
    }
    out
}

#[test]
fn a_run_reads_as_short_named_stages() {
    let dir = root().join("std-adapters/src/run");
    let mut long = Vec::new();
    let mut step = None;
    for p in sources(&dir) {
        let text = std::fs::read_to_string(&p).unwrap();
        let before_tests: String = text
            .lines()
            .take_while(|l| l.trim() != "#[cfg(test)]")
            .collect::<Vec<_>>()
            .join("\n");
        for (name, n) in functions(&before_tests) {
            if n > 80 {
                long.push(format!("{}: {name}, {n} lines", p.display()));
            }
            if name == "step" && p.ends_with("step.rs") {
                step = Some(n);
            }
        }
    }
    assert!(long.is_empty(), "functions over 80 lines in run/: {long:?}");
    let step = step.expect("Run::step in run/step.rs");
    assert!(step <= 60, "Run::step is {step} lines");
    assert_eq!(
        functions("fn a() {\n    x\n}\n\n    pub(super) fn b(\n        y: u8,\n    ) {\n    }\nfn c() {}\n"),
        [("a".to_string(), 3), ("b".to_string(), 4), ("c".to_string(), 1)]
    );
}
