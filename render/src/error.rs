//! The errors the library and the command line share: a [`UsageError`] is what the binary
//! prints like clap's own and exits with 2 for, wherever below the command line it is found.

/// A usage error found after parsing (two flags that do not go together): `main` prints it
/// like clap's own and exits with 2.
#[derive(Debug)]
pub struct UsageError(pub String);

impl std::fmt::Display for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

/// `error`, about the file `path` a flag named, as an error of `flag` that names the path once:
/// `--scene s.gltf: cannot read file…` where the error starts with the path (as the input and
/// scene errors do), else `--scene s.gltf: <error>`.
pub fn input_error(flag: &str, path: &std::path::Path, error: impl Into<anyhow::Error>) -> anyhow::Error {
    // `{:#}`: the causes too ("cannot read file: No such file or directory").
    let (shown, text) = (path.display().to_string(), format!("{:#}", error.into()));
    if text.starts_with(&shown) { anyhow::anyhow!("{flag} {text}") } else { anyhow::anyhow!("{flag} {shown}: {text}") }
}
