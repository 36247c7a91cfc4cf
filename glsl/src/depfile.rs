//! The make-style depfiles glslc writes with `-MD -MF` (`out.spv: a.comp include/b.glsl`).

use std::path::PathBuf;

/// Files a depfile names as dependencies of its target, the source itself included.
///
/// glslc writes paths unescaped, so a path containing a space comes back as two paths; cargo
/// treats a `rerun-if-changed` path that does not exist as always changed, so the cost of such
/// a folder is a rebuild every time, never a stale shader.
pub(crate) fn dependencies(text: &str) -> Vec<PathBuf> {
    // ": " rather than ':' so that a target path containing a colon still splits right.
    text.split_once(": ")
        .map(|(_, deps)| deps.split_whitespace().filter(|d| *d != "\\").map(PathBuf::from).collect())
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_every_prerequisite_across_continuation_lines() {
        let text = "/out/fill.comp.spv: /src/fill.comp \\\n /src/include/bindless.glsl /src/include/pattern.glsl\n";
        let deps = dependencies(text);
        let expected = ["/src/fill.comp", "/src/include/bindless.glsl", "/src/include/pattern.glsl"];
        assert_eq!(deps, expected.map(PathBuf::from));
    }

    #[test]
    fn a_file_without_a_rule_has_no_dependencies() {
        assert!(dependencies("").is_empty());
    }
}
