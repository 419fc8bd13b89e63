//! The README is a manual and the docs describe the product as it is: the README stays
//! short, no document outside CHANGELOG.md (and no code comment) speaks of sessions, issue numbers, commit
//! hashes or builds not kept, and every relative link points at a file that exists.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// README.md, PROTOCOL.md and every `docs/*.md`.
fn documents() -> Vec<PathBuf> {
    let r = root();
    let mut v = vec![r.join("README.md"), r.join("PROTOCOL.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(r.join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    v.extend(docs);
    v
}

#[test]
fn the_readme_is_a_manual_of_at_most_300_lines() {
    let text = std::fs::read_to_string(root().join("README.md")).unwrap();
    let lines = text.lines().count();
    assert!(lines <= 300, "README.md has {lines} lines");
    for must in [
        "not\nyet run on a physical board",
        "cargo run --release -p host-sim",
        "./ci.sh",
        "host-sim serve --pty",
    ] {
        let flat = must.replace('\n', " ");
        assert!(
            text.replace('\n', " ").contains(&flat),
            "README.md lacks {flat:?}"
        );
    }
}

/// A line speaking of the project's history rather than the product.
fn history(line: &str) -> Option<&'static str> {
    let l = line.to_lowercase();
    const ORDINALS: [&str; 21] = [
        "first",
        "second",
        "third",
        "fourth",
        "fifth",
        "sixth",
        "seventh",
        "eighth",
        "ninth",
        "tenth",
        "eleventh",
        "twelfth",
        "thirteenth",
        "fourteenth",
        "fifteenth",
        "sixteenth",
        "seventeenth",
        "eighteenth",
        "nineteenth",
        "twentieth",
        "this",
    ];
    if ORDINALS.iter().any(|o| l.contains(&format!("{o} session"))) {
        return Some("a session");
    }
    if l.contains("build not kept") || l.contains("builds not kept") {
        return Some("a build not kept");
    }
    if l.contains("git checkout") {
        return Some("a checkout of an old commit");
    }
    let words: Vec<&str> = l
        .split(|c: char| !c.is_ascii_alphanumeric() && c != '#')
        .collect();
    for w in words.windows(2) {
        if w[0] == "issue" && w[1].chars().next().is_some_and(|c| c.is_ascii_digit()) {
            return Some("an issue number");
        }
    }
    None
}

#[test]
fn no_document_speaks_of_the_projects_history() {
    let mut found = Vec::new();
    for p in documents() {
        let text = std::fs::read_to_string(&p).unwrap();
        for (n, line) in text.lines().enumerate() {
            if let Some(what) = history(line) {
                found.push(format!("{}:{}: {what}: {line}", p.display(), n + 1));
            }
        }
    }
    assert!(
        found.is_empty(),
        "history in the docs:\n{}",
        found.join("\n")
    );
}

/// Every `.rs` file under `dir`, recursively.
fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return;
    };
    for e in rd.flatten() {
        let p = e.path();
        if p.is_dir() {
            sources(&p, out);
        } else if p
            .extension()
            .is_some_and(|x| x == "rs" || x == "toml" || x == "sh")
        {
            out.push(p);
        }
    }
}

#[test]
fn no_code_comment_speaks_of_the_projects_history() {
    let r = root();
    let mut files = Vec::new();
    for d in [
        "core/src",
        "host-sim/src",
        "host-sim/tests",
        "firmware/src",
        "board-emu/src",
        "board-emu/tests",
        "bench-m4/src",
        "tests/tests",
        "scripts",
    ] {
        sources(&r.join(d), &mut files);
    }
    files.push(r.join("bench-budget.toml"));
    files.push(r.join("ci.sh"));
    let me = Path::new(file!()).file_name().unwrap();
    let mut found = Vec::new();
    for p in files.iter().filter(|p| p.file_name() != Some(me)) {
        let text = std::fs::read_to_string(p).unwrap();
        for (n, line) in text.lines().enumerate() {
            if let Some(what) = history(line) {
                found.push(format!("{}:{}: {what}: {line}", p.display(), n + 1));
            }
        }
    }
    assert!(files.len() > 100, "{} files", files.len());
    assert!(
        found.is_empty(),
        "history in the code:\n{}",
        found.join("\n")
    );
}

#[test]
fn every_relative_link_resolves() {
    let mut broken = Vec::new();
    for p in documents() {
        let text = std::fs::read_to_string(&p).unwrap();
        let dir = p.parent().unwrap();
        let mut rest = text.as_str();
        while let Some(i) = rest.find("](") {
            let after = &rest[i + 2..];
            let end = after.find(')').unwrap_or(after.len());
            let target = &after[..end];
            rest = &after[end..];
            if target.starts_with("http") || target.starts_with('#') || target.contains(' ') {
                continue;
            }
            let file = target.split('#').next().unwrap_or(target);
            // `../shared/` lies beside the repository, outside what CI clones.
            if file.is_empty()
                || file.starts_with("../shared/")
                || file.starts_with("../../shared/")
            {
                continue;
            }
            if !dir.join(file).exists() {
                broken.push(format!("{}: {target}", p.display()));
            }
        }
    }
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}

#[test]
fn the_history_check_sees_what_it_should() {
    assert_eq!(history("the twentieth session's trim"), Some("a session"));
    assert_eq!(history("(issue 21 part 3)"), Some("an issue number"));
    assert_eq!(
        history("measured on a build not kept"),
        Some("a build not kept")
    );
    assert_eq!(history("a PTY session paced by the host"), None);
    assert_eq!(history("the host issues a command"), None);
}
