//! The shape of the workspace, checked: the crates' direction of dependency and no module
//! import loops (docs/architecture.md).
//!
//! * Layers: every crate of the workspace may depend only on the project's crates listed
//!   below it in [`LAYERS`] (read from each `Cargo.toml`'s `[dependencies]`), and the core
//!   and the simulated drive pull in none of the I/O stacks ([`FORBIDDEN`], from
//!   `cargo tree -e normal`).
//! * Module loops: inside each crate, a module may use its own submodules; apart from that,
//!   the graph "module A names a path into module B" (`crate::…`, `super::…`, `self::…`)
//!   has no cycle. Test modules are left out.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The workspace's crates, bottom up, each with the project crates it may depend on.
const LAYERS: &[(&str, &str, &[&str])] = &[
    ("flexid-core", "crates/flexid-core", &[]),
    ("flexid-rt", "crates/flexid-rt", &["flexid-core"]),
    ("flexid-files", "crates/flexid-files", &["flexid-core"]),
    ("flexid-can", "drivers/flexid-can", &[]),
    ("flexid-canopen", "drivers/flexid-canopen", &["flexid-can"]),
    // EtherCAT (issue 18): the emulated ESC segment, the ethercrab link, the simulated servo
    // behind the ESC (flexid-core's plant physics, flexid-canopen's CiA 402 device state
    // machine) and the EtherCAT transport (flexid-canopen's CyclicDrive trait and scaling).
    // Not flexid-vdrive: the shared CiA 402 pieces already sit in flexid-canopen.
    (
        "flexid-ecat",
        "drivers/flexid-ecat",
        &["flexid-core", "flexid-can", "flexid-canopen"],
    ),
    // flexid-ecat: `flexid-vdrive --ethercat IFACE` serves its emulated servos on an
    // interface (issue 18 puts the simulated SubDevice in flexid-vdrive).
    (
        "flexid-vdrive",
        "drivers/flexid-vdrive",
        &[
            "flexid-core",
            "flexid-rt",
            "flexid-can",
            "flexid-canopen",
            "flexid-ecat",
        ],
    ),
    (
        "flexid-sweep",
        "crates/flexid-sweep",
        &[
            "flexid-core",
            "flexid-rt",
            "flexid-files",
            "flexid-can",
            "flexid-canopen",
        ],
    ),
    (
        "flexid-daemon",
        "crates/flexid-daemon",
        &[
            "flexid-core",
            "flexid-rt",
            "flexid-files",
            "flexid-sweep",
            "flexid-can",
            "flexid-canopen",
            "flexid-ecat",
            "flexid-vdrive",
        ],
    ),
    (
        "flexid",
        ".",
        &[
            "flexid-core",
            "flexid-rt",
            "flexid-files",
            "flexid-sweep",
            "flexid-daemon",
            "flexid-can",
            "flexid-canopen",
            "flexid-ecat",
            "flexid-vdrive",
        ],
    ),
];

/// External crates a crate must not have anywhere in its normal dependency tree.
const FORBIDDEN: &[(&str, &[&str])] = &[
    (
        "flexid-core",
        &[
            "tokio", "axum", "hyper", "reqwest", "plotters", "clap", "rumqttc",
        ],
    ),
    ("flexid-vdrive", &["tokio", "axum", "reqwest"]),
    (
        "flexid-rt",
        &["tokio", "axum", "hyper", "reqwest", "plotters"],
    ),
    (
        "flexid-sweep",
        &["tokio", "axum", "hyper", "reqwest", "plotters"],
    ),
];

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The names of the project's crates in the `[dependencies]` table of a `Cargo.toml`
/// (also `[target.'…'.dependencies]`; not dev- or build-dependencies).
fn project_dependencies(manifest: &Path) -> BTreeSet<String> {
    let text =
        std::fs::read_to_string(manifest).unwrap_or_else(|e| panic!("{}: {e}", manifest.display()));
    let mut out = BTreeSet::new();
    let mut in_deps = false;
    for line in text.lines() {
        let l = line.trim();
        if l.starts_with('[') {
            in_deps = l == "[dependencies]"
                || (l.starts_with("[target.") && l.ends_with(".dependencies]"));
            continue;
        }
        if !in_deps {
            continue;
        }
        let name = l.split(['=', '.']).next().unwrap_or("").trim().to_string();
        if name.starts_with("flexid") {
            out.insert(name);
        }
    }
    out
}

#[test]
fn crates_depend_only_on_the_layers_below() {
    let known: BTreeSet<&str> = LAYERS.iter().map(|l| l.0).collect();
    let mut bad = Vec::new();
    for (name, dir, allowed) in LAYERS {
        let deps = project_dependencies(&root().join(dir).join("Cargo.toml"));
        for d in &deps {
            assert!(
                known.contains(d.as_str()),
                "{name} depends on unknown crate {d}"
            );
            if !allowed.contains(&d.as_str()) {
                bad.push(format!("{name} -> {d}"));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "dependencies that point up or sideways: {bad:?}"
    );
}

#[test]
fn the_core_and_the_simulated_drive_pull_in_no_io_stacks() {
    for (krate, forbidden) in FORBIDDEN {
        let out = Command::new(env!("CARGO"))
            .current_dir(root())
            .args([
                "tree",
                "--offline",
                "-e",
                "normal",
                "--prefix",
                "none",
                "-p",
                krate,
            ])
            .output()
            .expect("run cargo tree");
        assert!(
            out.status.success(),
            "cargo tree -p {krate}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let tree = String::from_utf8_lossy(&out.stdout);
        let packages: BTreeSet<&str> = tree
            .lines()
            .filter_map(|l| l.split_whitespace().next())
            .collect();
        assert!(
            packages.len() > 3,
            "cargo tree -p {krate} listed nothing: {tree}"
        );
        let found: Vec<&&str> = forbidden
            .iter()
            .filter(|f| packages.contains(**f))
            .collect();
        assert!(found.is_empty(), "{krate} depends on {found:?}");
    }
}

/// A crate's modules: module path (`a::b`, empty for the crate root) -> file.
fn modules(src: &Path) -> BTreeMap<Vec<String>, PathBuf> {
    let mut out = BTreeMap::new();
    let mut stack = vec![src.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let p = entry.unwrap().path();
            if p.is_dir() {
                stack.push(p);
                continue;
            }
            if p.extension().and_then(|e| e.to_str()) != Some("rs") {
                continue;
            }
            let rel = p.strip_prefix(src).unwrap().with_extension("");
            let mut parts: Vec<String> = rel
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect();
            if matches!(
                parts.last().map(String::as_str),
                Some("mod" | "lib" | "main")
            ) {
                parts.pop();
            }
            if parts.first().map(String::as_str) == Some("bin") {
                continue; // binaries are crates of their own
            }
            out.insert(parts, p);
        }
    }
    out
}

fn is_test_module(m: &[String]) -> bool {
    m.iter()
        .any(|p| p == "tests" || p.starts_with("tests_") || p.ends_with("_tests"))
}

/// The source without comments and without a trailing `#[cfg(test)] mod … { … }`.
fn code_of(text: &str) -> String {
    let cut = text
        .find("#[cfg(test)]\nmod ")
        .filter(|&i| text[i..].lines().nth(1).is_some_and(|l| l.contains('{')))
        .unwrap_or(text.len());
    text[..cut]
        .lines()
        .map(|l| match l.find("//") {
            Some(i) => &l[..i],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The paths starting with `crate`, `super` or `self` in `code`, with one level of
/// `{a, b::c}` groups expanded.
fn module_paths(code: &str) -> Vec<Vec<String>> {
    let b = code.as_bytes();
    let ident = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts = ["crate::", "super::", "self::"]
            .iter()
            .find(|k| b[i..].starts_with(k.as_bytes()));
        if starts.is_none() || (i > 0 && ident(b[i - 1])) {
            i += 1;
            continue;
        }
        let mut j = i;
        let mut segs = Vec::new();
        loop {
            let s = j;
            while j < b.len() && ident(b[j]) {
                j += 1;
            }
            segs.push(code[s..j].to_string());
            if b[j..].starts_with(b"::") && j + 2 < b.len() && ident(b[j + 2]) {
                j += 2;
            } else {
                break;
            }
        }
        if b[j..].starts_with(b"::{") {
            // the group up to its matching brace, split at its top-level commas
            let (mut depth, mut end, mut items, mut start) = (0usize, b.len(), Vec::new(), j + 3);
            for (k, &c) in b.iter().enumerate().skip(j + 2) {
                match c {
                    b'{' => depth += 1,
                    b'}' if depth == 1 => {
                        end = k;
                        break;
                    }
                    b'}' => depth -= 1,
                    b',' if depth == 1 => {
                        items.push(&code[start..k]);
                        start = k + 1;
                    }
                    _ => {}
                }
            }
            items.push(&code[start.min(end)..end]);
            for item in items {
                let item = item.split(" as ").next().unwrap_or("");
                let mut p = segs.clone();
                p.extend(
                    item.split("::")
                        .map(str::trim)
                        .take_while(|x| !x.is_empty() && x.bytes().all(ident))
                        .map(String::from),
                );
                if p.len() > segs.len() {
                    out.push(p);
                }
            }
            j = end;
        } else {
            out.push(segs);
        }
        i = j.max(i + 1);
    }
    out
}

/// The module a path names from module `cur` (its longest prefix that is a module).
fn resolve(
    mods: &BTreeMap<Vec<String>, PathBuf>,
    cur: &[String],
    path: &[String],
) -> Option<Vec<String>> {
    let (mut base, rest): (Vec<String>, &[String]) = match path[0].as_str() {
        "crate" => (Vec::new(), &path[1..]),
        "self" => (cur.to_vec(), &path[1..]),
        "super" => {
            let mut b = cur.to_vec();
            let mut k = 0;
            while k < path.len() && path[k] == "super" {
                b.pop();
                k += 1;
            }
            (b, &path[k..])
        }
        _ => return None,
    };
    let mut best = mods.contains_key(&base).then(|| base.clone());
    for seg in rest {
        base.push(seg.clone());
        if mods.contains_key(&base) {
            best = Some(base.clone());
        } else {
            break;
        }
    }
    best
}

/// Edges A -> B where A names a path into B, B neither A nor one of A's submodules.
fn module_graph(src: &Path) -> BTreeMap<Vec<String>, BTreeSet<Vec<String>>> {
    let mods = modules(src);
    let mut g: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = BTreeMap::new();
    for (m, file) in &mods {
        if is_test_module(m) {
            continue;
        }
        let code = code_of(&std::fs::read_to_string(file).unwrap());
        for p in module_paths(&code) {
            let Some(t) = resolve(&mods, m, &p) else {
                continue;
            };
            if t.starts_with(m) || is_test_module(&t) {
                continue;
            }
            g.entry(m.clone()).or_default().insert(t);
        }
    }
    g
}

/// The strongly connected components with more than one module (Tarjan).
fn cycles(g: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>) -> Vec<Vec<String>> {
    struct T<'a> {
        g: &'a BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
        index: BTreeMap<&'a Vec<String>, usize>,
        low: BTreeMap<&'a Vec<String>, usize>,
        stack: Vec<&'a Vec<String>>,
        on: BTreeSet<&'a Vec<String>>,
        out: Vec<Vec<String>>,
    }
    fn visit<'a>(t: &mut T<'a>, v: &'a Vec<String>) {
        let n = t.index.len();
        t.index.insert(v, n);
        t.low.insert(v, n);
        t.stack.push(v);
        t.on.insert(v);
        if let Some(ws) = t.g.get(v) {
            for w in ws {
                if !t.index.contains_key(w) {
                    visit(t, w);
                    let lw = t.low[w];
                    let lv = t.low.get_mut(v).unwrap();
                    *lv = (*lv).min(lw);
                } else if t.on.contains(w) {
                    let iw = t.index[w];
                    let lv = t.low.get_mut(v).unwrap();
                    *lv = (*lv).min(iw);
                }
            }
        }
        if t.low[v] == t.index[v] {
            let mut comp = Vec::new();
            loop {
                let w = t.stack.pop().unwrap();
                t.on.remove(w);
                comp.push(w.join("::"));
                if w == v {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                t.out.push(comp);
            }
        }
    }
    let mut t = T {
        g,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        out: Vec::new(),
    };
    let nodes: BTreeSet<&Vec<String>> = g.keys().chain(g.values().flatten()).collect();
    for v in nodes {
        if !t.index.contains_key(v) {
            visit(&mut t, v);
        }
    }
    t.out
}

#[test]
fn the_cycle_finder_finds_a_loop_and_passes_a_tree() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path();
    std::fs::create_dir_all(src.join("a")).unwrap();
    std::fs::write(src.join("lib.rs"), "mod a; mod b; mod c;").unwrap();
    std::fs::write(
        src.join("a/mod.rs"),
        "mod inner; use self::inner::X; // crate::c::Z in a comment\n",
    )
    .unwrap();
    std::fs::write(src.join("a/inner.rs"), "use super::super::b::Y;").unwrap();
    std::fs::write(src.join("b.rs"), "pub struct Y; fn f() { crate::c::g() }").unwrap();
    std::fs::write(src.join("c.rs"), "pub fn g() {}").unwrap();
    assert_eq!(cycles(&module_graph(src)), Vec::<Vec<String>>::new());
    // c -> a::inner -> b -> c, through a group import
    std::fs::write(src.join("c.rs"), "use crate::{a::inner, d}; pub fn g() {}").unwrap();
    assert_eq!(
        cycles(&module_graph(src)),
        vec![vec!["a::inner".to_string(), "b".into(), "c".into()]]
    );
}

#[test]
fn no_module_imports_another_that_imports_it_back() {
    let mut srcs = vec![root().join("src")];
    for (_, dir, _) in LAYERS {
        if *dir != "." {
            srcs.push(root().join(dir).join("src"));
        }
    }
    let mut found = Vec::new();
    for src in &srcs {
        let g = module_graph(src);
        assert!(!g.is_empty(), "{}: no module graph", src.display());
        for c in cycles(&g) {
            found.push(format!("{}: {}", src.display(), c.join(" <-> ")));
        }
    }
    assert!(
        found.is_empty(),
        "module import loops:\n{}",
        found.join("\n")
    );
}
