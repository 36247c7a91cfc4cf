//! README.md and docs/ tell the truth a new user checks first: the commands' scene paths exist in
//! a clone and every document they point to is in the repository (tests/docs_blocks.rs runs the
//! commands themselves).

use std::path::{Path, PathBuf};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn read(path: &str) -> String {
    std::fs::read_to_string(root().join(path)).unwrap()
}

/// The words of README's shell blocks, one command line per item (continuations joined,
/// comments dropped).
fn shell_lines(markdown: &str) -> Vec<String> {
    let mut lines = Vec::new();
    let mut in_sh = false;
    let mut pending = String::new();
    for line in markdown.lines() {
        if line.starts_with("```") {
            in_sh = line == "```sh";
            continue;
        }
        if !in_sh {
            continue;
        }
        let code = line.split(" # ").next().unwrap_or("").trim_end();
        match code.strip_suffix('\\') {
            Some(head) => pending.push_str(head),
            None => {
                pending.push_str(code);
                lines.push(std::mem::take(&mut pending));
            }
        }
    }
    lines
}

/// Every `--scene FILE` of README's commands names `default`, `$SPONZA` (whose source the
/// "Scenes" section gives) or a file of the repository.
#[test]
fn readme_scene_paths_exist_in_a_clone() {
    let readme = read("README.md");
    assert!(
        readme.contains("## Scenes") && readme.contains("glTF-Sample-Assets"),
        "README says where scenes come from"
    );
    let mut seen = 0;
    for line in shell_lines(&readme) {
        let words = shlex::split(&line).unwrap_or_default();
        for pair in words.windows(2).filter(|w| w[0] == "--scene") {
            seen += 1;
            let scene = &pair[1];
            assert!(scene == "default" || scene == "$SPONZA" || root().join(scene).is_file(), "{line}");
        }
    }
    assert!(seen >= 3, "README's commands name scenes");
    for line in readme.lines().filter(|l| l.starts_with("args = ")) {
        let args = line.trim_start_matches("args = \"").split('"').next().unwrap();
        let words = shlex::split(args).unwrap();
        let scene = &words[words.iter().position(|w| w == "--scene").unwrap() + 1];
        assert!(root().join(scene).is_file(), "{line}");
    }
}

/// Every `NAME.md` that README.md or docs/*.md names is a file of the repository (docs/RESULTS.md
/// used to send readers to DESIGN.md, which is not).
#[test]
fn documents_point_only_to_documents_in_the_repository() {
    let mut names = Vec::new();
    let mut stack = vec![root().to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap().flatten() {
            let path = entry.path();
            let name = entry.file_name().to_string_lossy().into_owned();
            if path.is_dir() && !name.starts_with('.') && name != "target" {
                stack.push(path);
            } else if name.ends_with(".md") {
                names.push(name);
            }
        }
    }
    let mut documents: Vec<PathBuf> = vec![root().join("README.md")];
    documents.extend(
        std::fs::read_dir(root().join("docs"))
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|e| e == "md")),
    );
    for doc in documents {
        let text = std::fs::read_to_string(&doc).unwrap();
        let words = text.split(|c: char| !(c.is_ascii_alphanumeric() || "_./-".contains(c)));
        for word in words.map(|w| w.trim_end_matches('.')).filter(|w| w.ends_with(".md")) {
            let name = word.rsplit('/').next().unwrap();
            assert!(names.iter().any(|n| n == name), "{} names {word}, which is not in the repository", doc.display());
        }
    }
}
