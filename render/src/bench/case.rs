//! A case of `parallax bench`: render arguments shared by a set of cells.

use std::path::PathBuf;

use anyhow::{Result, anyhow};

/// Render arguments shared by a set of cells (scene, light field, resolution, ...).
#[derive(Clone, Debug, PartialEq)]
pub struct Case {
    /// None for `--common`, whose cells keep ids without a case prefix.
    pub name: Option<String>,
    pub args: String,
    /// Reference views to measure the case's cells against.
    pub reference: Option<PathBuf>,
}

impl Case {
    /// The render arguments as words, split as a POSIX shell would (quotes keep a path with
    /// spaces in one word).
    pub fn words(&self) -> Result<Vec<String>> {
        shlex::split(&self.args).ok_or_else(|| anyhow!("`{}`: a quote is not closed: close it", self.args))
    }
}
