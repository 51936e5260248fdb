//! Imports go one way: the rooms of `src/` import only rooms before them in the data's order
//! (the order `lib.rs` states), and no two modules of a room import each other, directly or
//! round a circle. Read from the `crate::` and `super::` paths of the code itself (tests and
//! comments aside), so that a new upward arrow fails here, not in review.

// Test code: a failed unwrap is a failed test, with its location.
#![allow(clippy::unwrap_used)]

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The rooms of `src/` in the order the data flows through them (as `lib.rs` states): each may
/// import only rooms before it. `testing` holds the unit tests' fixtures and may import any.
const ORDER: [&str; 16] = [
    "board",
    "trace",
    "error",
    "poly",
    "fit",
    "physics",
    "design",
    "evidence",
    "effects",
    "file",
    "modelling",
    "pipeline",
    "export",
    "report",
    "cli",
    "testing",
];

/// A module: its path below the crate root (`["design", "inverse"]`).
type Module = Vec<String>;

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// Every `.rs` file below `dir`.
fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The module a file is (`src/design/inverse/mod.rs` and `src/design/inverse.rs` are
/// `design::inverse`); `None` for the crate root and the binary.
fn module_of(file: &Path) -> Option<Module> {
    let rel = file.strip_prefix(src()).unwrap().with_extension("");
    let mut parts: Module = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if parts.last().is_some_and(|p| p == "mod") {
        parts.pop();
    }
    match parts.as_slice() {
        [one] if one == "lib" || one == "main" => None,
        _ => Some(parts),
    }
}

/// Whether `parts` names a module file (`src/a/b.rs` or `src/a/b/`).
fn is_module(parts: &[String]) -> bool {
    let p = parts.iter().fold(src(), |p, s| p.join(s));
    p.with_extension("rs").is_file() || p.is_dir()
}

/// The node a path lands on: the room's second-level module when it names one
/// (`design::inverse`), else the room (`fit` for `fit::Test`).
fn node(parts: &[String]) -> Module {
    match parts {
        [room, sub, ..] if is_module(&parts[..2]) => vec![room.clone(), sub.clone()],
        [room, ..] => vec![room.clone()],
        [] => Vec::new(),
    }
}

/// The code of a file without its comments and its test-only modules (`#[cfg(test)] mod x
/// { .. }`: the tests of a module may use what the module may not).
fn code(text: &str) -> String {
    let text: String = text
        .lines()
        .map(|l| l.find("//").map_or(l, |k| &l[..k]))
        .collect::<Vec<_>>()
        .join("\n");
    let mut out = String::with_capacity(text.len());
    let mut rest = text.as_str();
    while let Some(k) = rest.find("#[cfg(test)]") {
        out.push_str(&rest[..k]);
        let after = &rest[k + "#[cfg(test)]".len()..];
        // Other attributes may stand between the cfg and the item.
        let mut item = after.trim_start();
        while item.starts_with("#[") {
            item = item.find(']').map_or("", |e| item[e + 1..].trim_start());
        }
        let item = item
            .strip_prefix("pub(crate) ")
            .or_else(|| item.strip_prefix("pub "))
            .unwrap_or(item);
        if !item.starts_with("mod ") {
            rest = after;
            continue;
        }
        rest = match (item.find(';'), item.find('{')) {
            (Some(semi), Some(open)) if semi < open => &item[semi + 1..],
            (_, Some(open)) => &item[open + block_len(&item[open..])..],
            (Some(semi), None) => &item[semi + 1..],
            (None, None) => "",
        };
    }
    out.push_str(rest);
    out
}

/// The length of the block `text` starts with (at its `{`), to the matching `}`: braces in
/// string and character literals do not count.
fn block_len(text: &str) -> usize {
    let (mut depth, mut in_string, mut escaped) = (0usize, false, false);
    let bytes = text.as_bytes();
    for (i, &b) in bytes.iter().enumerate() {
        if in_string {
            match b {
                _ if escaped => escaped = false,
                b'\\' => escaped = true,
                b'"' => in_string = false,
                _ => {}
            }
            continue;
        }
        let quoted = i > 0 && bytes.get(i - 1) == Some(&b'\'') && bytes.get(i + 1) == Some(&b'\'');
        match b {
            b'"' => in_string = true,
            _ if quoted => {}
            b'{' => depth += 1,
            b'}' => {
                depth = depth.saturating_sub(1);
                if depth == 0 {
                    return i + 1;
                }
            }
            _ => {}
        }
    }
    text.len()
}

fn ident(text: &str) -> Option<(&str, &str)> {
    let end = text
        .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .unwrap_or(text.len());
    let first = text.chars().next()?;
    (end > 0 && (first.is_ascii_alphabetic() || first == '_')).then(|| text.split_at(end))
}

/// The paths `text` (just after `crate::` or `super::`) names, `prefix` in front of each:
/// `a::b::C` or a group `{a::b, c::{d, e}}`.
fn paths(prefix: &[String], text: &str) -> Vec<Module> {
    let text = text.trim_start();
    if let Some(group) = text.strip_prefix('{') {
        let mut out = Vec::new();
        let (mut depth, mut start) = (0usize, 0usize);
        for (i, c) in group.char_indices() {
            match c {
                '{' => depth += 1,
                '}' if depth == 0 => {
                    out.extend(item(prefix, &group[start..i]));
                    break;
                }
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    out.extend(item(prefix, &group[start..i]));
                    start = i + 1;
                }
                _ => {}
            }
        }
        return out;
    }
    item(prefix, text)
}

fn item(prefix: &[String], text: &str) -> Vec<Module> {
    let Some((name, rest)) = ident(text.trim_start()) else {
        return Vec::new();
    };
    if name == "self" {
        return vec![prefix.to_vec()];
    }
    if rest.starts_with('!') {
        // A macro: `#[macro_export]` puts it at the crate root; it belongs where it is defined.
        return macro_home(name).into_iter().collect();
    }
    let mut path = prefix.to_vec();
    path.push(name.to_string());
    match rest.strip_prefix("::") {
        Some(rest) => {
            let deeper = paths(&path, rest);
            if deeper.is_empty() {
                vec![path]
            } else {
                deeper
            }
        }
        None => vec![path],
    }
}

/// The module that defines the macro `name` (`macro_rules! name`), from every file of `src/`
/// read once.
fn macro_home(name: &str) -> Option<Module> {
    static HOMES: std::sync::OnceLock<BTreeMap<String, Module>> = std::sync::OnceLock::new();
    HOMES
        .get_or_init(|| {
            let mut all = Vec::new();
            files(&src(), &mut all);
            let mut homes = BTreeMap::new();
            for f in all {
                let (Ok(text), Some(module)) = (std::fs::read_to_string(&f), module_of(&f)) else {
                    continue;
                };
                for (k, _) in text.match_indices("macro_rules! ") {
                    if let Some((name, _)) = ident(&text[k + "macro_rules! ".len()..]) {
                        homes.insert(name.to_string(), module.clone());
                    }
                }
            }
            homes
        })
        .get(name)
        .cloned()
}

/// Every import arrow between nodes: `(from, to)`, with the file that draws it.
fn arrows() -> BTreeMap<(Module, Module), String> {
    let mut all = Vec::new();
    files(&src(), &mut all);
    let mut out = BTreeMap::new();
    for file in all {
        let Some(module) = module_of(&file) else {
            continue;
        };
        let text = code(&std::fs::read_to_string(&file).unwrap());
        let shown = file.strip_prefix(src()).unwrap().display().to_string();
        let from = node(&module);
        let mut add = |to: Module| {
            if !to.is_empty() && to != from {
                out.entry((from.clone(), to))
                    .or_insert_with(|| shown.clone());
            }
        };
        for (k, _) in text.match_indices("crate::") {
            if text[..k].ends_with(|c: char| c.is_ascii_alphanumeric() || c == '_' || c == '$') {
                continue;
            }
            for p in paths(&[], &text[k + "crate::".len()..]) {
                add(node(&p));
            }
        }
        let mut rest = text.as_str();
        while let Some(k) = rest.find("super::") {
            let before = &rest[..k];
            let mut after = &rest[k..];
            if before.ends_with("::") || before.ends_with(|c: char| c.is_ascii_alphanumeric()) {
                rest = &after["super::".len()..];
                continue;
            }
            let mut up = 0;
            while let Some(r) = after.strip_prefix("super::") {
                up += 1;
                after = r;
            }
            if let Some(base) = module.len().checked_sub(up).filter(|&n| n > 0) {
                for p in paths(&module[..base], after) {
                    add(node(&p));
                }
            }
            rest = after;
        }
    }
    out
}

fn name(m: &Module) -> String {
    m.join("::")
}

#[test]
fn imports_go_down_the_rooms_and_round_no_circle() {
    let arrows = arrows();
    assert!(
        arrows.len() > 100,
        "the scan found too few imports: {}",
        arrows.len()
    );
    let rank = |room: &str| ORDER.iter().position(|r| *r == room);
    let mut wrong = Vec::new();
    for ((from, to), file) in &arrows {
        match (rank(&from[0]), rank(&to[0])) {
            (Some(a), Some(b)) if b > a => wrong.push(format!(
                "{file}: {} imports {}, a room after it (the order: {})",
                name(from),
                name(to),
                ORDER.join(", ")
            )),
            (None, _) => wrong.push(format!("{file}: room {} is not in ORDER", from[0])),
            (_, None) => wrong.push(format!(
                "{file}: {} imports {}, which is not a room of src/ (a crate-root re-export?)",
                name(from),
                name(to)
            )),
            _ => {}
        }
    }
    // Circles between the modules of a room (a room's own `mod.rs` is its modules' common
    // parent and is left out): depth-first search for a back edge.
    let mut graph: BTreeMap<&Module, BTreeSet<&Module>> = BTreeMap::new();
    for (from, to) in arrows.keys() {
        if from.len() == 2 && to.len() == 2 {
            graph.entry(from).or_default().insert(to);
        }
    }
    fn visit<'a>(
        v: &'a Module,
        graph: &BTreeMap<&'a Module, BTreeSet<&'a Module>>,
        path: &mut Vec<&'a Module>,
        done: &mut BTreeSet<&'a Module>,
        circles: &mut Vec<String>,
    ) {
        if let Some(k) = path.iter().position(|p| *p == v) {
            let mut circle: Vec<String> = path[k..].iter().map(|m| name(m)).collect();
            circle.push(name(v));
            circles.push(circle.join(" -> "));
            return;
        }
        if !done.insert(v) {
            return;
        }
        path.push(v);
        for w in graph.get(v).into_iter().flatten() {
            visit(w, graph, path, done, circles);
        }
        path.pop();
    }
    let mut circles = Vec::new();
    let mut done = BTreeSet::new();
    for v in graph.keys() {
        visit(v, &graph, &mut Vec::new(), &mut done, &mut circles);
    }
    wrong.extend(
        circles
            .into_iter()
            .map(|c| format!("a circle of imports: {c}")),
    );
    assert!(wrong.is_empty(), "\n{}", wrong.join("\n"));
}

/// The checker itself sees an upward arrow, a group import and a circle.
#[test]
fn the_scan_reads_groups_and_super_paths() {
    let p = |s: &str| s.split("::").map(String::from).collect::<Module>();
    assert_eq!(
        paths(&[], "{fit::{self, Test}, design::inverse::Design};"),
        vec![p("fit"), p("fit::Test"), p("design::inverse::Design")]
    );
    assert_eq!(
        paths(&p("design"), "quantise::FixedPlan::new(d)"),
        vec![p("design::quantise::FixedPlan::new")]
    );
    assert_eq!(node(&p("design::inverse::Design")), p("design::inverse"));
    assert_eq!(node(&p("fit::Test")), p("fit"));
    assert_eq!(
        code("use crate::a; // crate::b\n#[cfg(test)]\nmod t { let c = '{'; f(\"}\"); use crate::c; }\nuse crate::d;"),
        "use crate::a; \n\nuse crate::d;"
    );
    assert_eq!(paths(&[], "outln!(\"x\")"), vec![p("cli::console")]);
    let arrows = arrows();
    assert!(
        arrows.contains_key(&(p("cli"), p("pipeline"))),
        "the CLI asks the pipeline"
    );
    assert!(arrows.contains_key(&(p("design::inverse"), p("design::quantise"))));
}
