//! No dead reference in the repository's prose: every relative link of a Markdown file (`[text](path)`,
//! `<img src="path">`) and every file path in backticks, in the Markdown files and in the code's comments
//! and docs (`` `src/rod/solver.rs` ``, `` `tests/gpu/step.rs` ``), names a file or folder that exists.

use std::path::{Path, PathBuf};

/// The folders whose files are read (and, recursively, their subfolders), relative to the repository.
const READ: &[&str] = &[".", "docs", "src", "tests", "examples", "benches", "support", "fuzz", ".ci"];

/// The folders a backticked path must start with to be checked.
const ROOTS: &[&str] = &["src/", "tests/", "examples/", "benches/", "docs/", "assets/", "support/", "fuzz/", ".ci/"];

fn text_files(directory: &Path, recurse: bool, found: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(directory) else { return };
    for entry in entries.flatten() {
        let path = entry.path();
        let name = entry.file_name().to_string_lossy().into_owned();
        if path.is_dir() {
            if recurse && !name.starts_with('.') && name != "target" {
                text_files(&path, true, found);
            }
        } else if [".md", ".rs", ".wgsl", ".sh", ".toml"].iter().any(|extension| name.ends_with(extension))
            || name == "run"
        {
            found.push(path);
        }
    }
}

/// The relative link targets of Markdown `text`: `](target)` and `src="target"`, anchors and web
/// addresses left out.
fn markdown_links(text: &str) -> Vec<String> {
    let mut links = Vec::new();
    for (opening, closing) in [("](", ')'), ("src=\"", '"')] {
        for (at, _) in text.match_indices(opening) {
            let rest = &text[at + opening.len()..];
            let Some(end) = rest.find(closing) else { continue };
            let target = rest[..end].split('#').next().unwrap_or_default().trim();
            if !target.is_empty() && !target.contains("://") && !target.starts_with("mailto:") {
                links.push(target.to_string());
            }
        }
    }
    links
}

/// The repository paths in backticks in `text`: `` `src/…` ``, `` `tests/…` `` and so on, with an
/// extension or a trailing slash, and no spaces, wildcards or placeholders.
fn backticked_paths(text: &str) -> Vec<String> {
    text.split('`')
        .skip(1)
        .step_by(2)
        .filter(|quoted| ROOTS.iter().any(|root| quoted.starts_with(root)))
        .filter(|quoted| !quoted.contains([' ', '*', '<', '{', '$', '(']))
        .map(|quoted| quoted.split(':').next().unwrap_or_default().to_string())
        .filter(|path| path.ends_with('/') || path.rsplit('/').next().is_some_and(|name| name.contains('.')))
        .collect()
}

#[test]
fn every_relative_link_and_backticked_path_names_a_file_that_exists() {
    let repository = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    for folder in READ {
        text_files(&repository.join(folder), *folder != ".", &mut files);
    }
    assert!(files.len() > 100, "{} files read: the test reads the wrong folder", files.len());
    let mut checked = 0;
    let mut dead = Vec::new();
    for file in &files {
        let text = std::fs::read_to_string(file).unwrap();
        let relative = file.strip_prefix(repository).unwrap().to_string_lossy().into_owned();
        if relative.ends_with(".md") {
            for link in markdown_links(&text) {
                checked += 1;
                let target = file.parent().unwrap().join(&link);
                if !target.exists() {
                    dead.push(format!("{relative}: link to {link}"));
                }
            }
        }
        for path in backticked_paths(&text) {
            checked += 1;
            if !repository.join(&path).exists() {
                dead.push(format!("{relative}: `{path}`"));
            }
        }
    }
    println!("{checked} references in {} files", files.len());
    assert!(checked > 100, "only {checked} references found: the test finds too few");
    assert!(dead.is_empty(), "{} references to nothing:\n{}", dead.len(), dead.join("\n"));
}

#[test]
fn the_reference_finders_find_what_they_should() {
    assert_eq!(
        markdown_links("see [a](docs/a.md#x) and [b](https://b) <img src=\"assets/c.png\">"),
        ["docs/a.md", "assets/c.png"]
    );
    assert_eq!(
        backticked_paths("`src/rod/solver.rs`, `tests/gpu/`, `src/x.rs:12`, `src/*.rs`, `rod::Rod`"),
        ["src/rod/solver.rs", "tests/gpu/", "src/x.rs"]
    );
}
