//! The documentation a newcomer reads: README.md short, its two set-up commands near the
//! top and the same as CI runs, every relative link of README.md and docs/*.md pointing at
//! a file (and heading) that exists.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn readme_is_short_and_starts_with_the_two_commands() {
    let text = read(&root().join("README.md"));
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines.len() < 300, "README.md has {} lines", lines.len());
    let first: String = lines[..lines.len().min(30)].join("\n");
    assert!(
        first.contains("cargo build --release --workspace && target/release/flexid demo"),
        "the main job's command is not in the first 30 lines"
    );
    assert!(
        first.contains("scripts/test.sh"),
        "the test command is not in the first 30 lines"
    );
    let ci = read(&root().join(".ci/run"));
    assert!(
        ci.contains("scripts/test.sh"),
        ".ci/run does not run the README's test command"
    );
}

/// GitHub's anchor of a heading: lower case, spaces to '-', punctuation dropped.
fn anchor(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || *c == '-' || *c == '_' || *c == ' ')
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

fn anchors(text: &str) -> Vec<String> {
    text.lines()
        .filter(|l| l.starts_with('#'))
        .map(|l| anchor(l.trim_start_matches('#')))
        .collect()
}

/// The targets of the Markdown links `](target)` outside fenced code blocks.
fn links(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        let mut rest = line;
        while let Some(i) = rest.find("](") {
            let tail = &rest[i + 2..];
            let Some(j) = tail.find(')') else { break };
            out.push(tail[..j].to_string());
            rest = &tail[j..];
        }
    }
    out
}

#[test]
fn every_relative_link_of_the_documentation_resolves() {
    let mut pages = vec![root().join("README.md")];
    for e in std::fs::read_dir(root().join("docs")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().and_then(|x| x.to_str()) == Some("md") {
            pages.push(p);
        }
    }
    assert!(pages.len() >= 8, "README and the docs pages: {pages:?}");
    let mut bad = Vec::new();
    for page in &pages {
        let text = read(page);
        for link in links(&text) {
            if link.contains("://") || link.starts_with("mailto:") {
                continue;
            }
            let (path, frag) = link.split_once('#').unwrap_or((&link, ""));
            let target = if path.is_empty() {
                page.clone()
            } else {
                page.parent().unwrap().join(path)
            };
            if !target.exists() {
                bad.push(format!("{}: {link} (no file)", page.display()));
                continue;
            }
            if !frag.is_empty()
                && target.extension().and_then(|x| x.to_str()) == Some("md")
                && !anchors(&read(&target)).iter().any(|a| a == frag)
            {
                bad.push(format!("{}: {link} (no heading)", page.display()));
            }
        }
    }
    assert!(bad.is_empty(), "broken links:\n{}", bad.join("\n"));
}
