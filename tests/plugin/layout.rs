//! The crate's layout, as the crate guide (`src/lib.rs`, "Architecture") writes it down: each top-level
//! module may use only those below it in the layer order, so the modules import each other in no circle.
//! Reads the sources: every `crate::module` path in code (comments and doc links left out) is an import.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The top-level modules, each with its layer: a module may use those of lower layers only.
const LAYERS: &[(&str, u32)] = &[
    ("rod", 0),
    ("parallel", 0),
    ("schedule", 1),
    ("gpu", 1),
    ("simulation", 2),
    ("collision", 3),
    ("detail", 3),
    ("followers", 3),
    ("wind", 3),
    ("volume", 4),
    ("groom", 5),
    ("scalp", 6),
    ("render", 7),
    ("debug", 8),
    ("lib", 9),
];

/// The sideways imports the guide allows between modules of one layer: none.
const ALLOWED_SIDEWAYS: &[(&str, &str)] = &[];

fn layer(module: &str) -> Option<u32> {
    LAYERS.iter().find(|(name, _)| *name == module).map(|&(_, layer)| layer)
}

fn rust_files(directory: &Path, found: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(directory).expect("src/ is readable").flatten() {
        let path = entry.path();
        if path.is_dir() {
            rust_files(&path, found);
        } else if path.extension().is_some_and(|extension| extension == "rs") {
            found.push(path);
        }
    }
}

/// The modules each top-level module names through `crate::…` in its code, with the files that do.
fn imports() -> BTreeMap<(String, String), BTreeSet<String>> {
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&source, &mut files);
    let mut edges: BTreeMap<(String, String), BTreeSet<String>> = BTreeMap::new();
    for file in files {
        let relative = file.strip_prefix(&source).unwrap().to_string_lossy().replace('\\', "/");
        let from = relative.split('/').next().unwrap().trim_end_matches(".rs").to_string();
        assert!(layer(&from).is_some(), "{relative}: the top-level module `{from}` has no layer in this test");
        let text = std::fs::read_to_string(&file).unwrap();
        for line in text.lines() {
            let code = line.split("//").next().unwrap_or_default();
            for (at, _) in code.match_indices("crate::") {
                let rest = &code[at + "crate::".len()..];
                let to: String = rest.chars().take_while(|c| c.is_ascii_lowercase() || *c == '_').collect();
                if layer(&to).is_some() && to != from {
                    edges.entry((from.clone(), to)).or_default().insert(relative.clone());
                }
            }
        }
    }
    edges
}

#[test]
fn no_module_imports_one_above_it() {
    let edges = imports();
    assert!(edges.len() > 20, "the import scan found too little to be reading the sources ({} edges)", edges.len());
    let wrong: Vec<String> = edges
        .iter()
        .filter(|((from, to), _)| {
            let (from_layer, to_layer) = (layer(from).unwrap(), layer(to).unwrap());
            to_layer > from_layer
                || (to_layer == from_layer && !ALLOWED_SIDEWAYS.contains(&(from.as_str(), to.as_str())))
        })
        .map(|((from, to), files)| {
            format!("{from} → {to} (in {})", files.iter().cloned().collect::<Vec<_>>().join(", "))
        })
        .collect();
    assert!(wrong.is_empty(), "imports against the layer order:\n{}", wrong.join("\n"));
}

#[test]
fn modules_import_each_other_in_no_circle() {
    let edges = imports();
    let mut graph: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    for (from, to) in edges.keys() {
        graph.entry(from.as_str()).or_default().push(to.as_str());
    }
    // Depth-first search; a module met again while it is on the path closes a circle.
    fn visit<'a>(
        module: &'a str,
        graph: &BTreeMap<&'a str, Vec<&'a str>>,
        path: &mut Vec<&'a str>,
        done: &mut BTreeSet<&'a str>,
    ) -> Option<Vec<&'a str>> {
        if let Some(start) = path.iter().position(|&on_path| on_path == module) {
            let mut circle = path[start..].to_vec();
            circle.push(module);
            return Some(circle);
        }
        if !done.insert(module) {
            return None;
        }
        path.push(module);
        for &next in graph.get(module).into_iter().flatten() {
            if let Some(circle) = visit(next, graph, path, done) {
                return Some(circle);
            }
        }
        path.pop();
        None
    }
    let mut done = BTreeSet::new();
    for &module in graph.keys() {
        let circle = visit(module, &graph, &mut Vec::new(), &mut done);
        assert!(circle.is_none(), "modules import each other in a circle: {}", circle.unwrap().join(" → "));
    }
}
