//! Where the outputs read a finished view from: the renderer of this process, or (rank 0 of a
//! render over several ranks) the views other ranks sent, with its own renderer for the rest.

use std::collections::{BTreeSet, HashMap};

use parallax_graph::FamilyId;
use parallax_passes::{LightFieldRenderer, PassError};

/// Reads resource `family` of a finished view, as `LightFieldRenderer::read` does.
pub trait ViewSource {
    fn read_view(&mut self, family: FamilyId, view: u32) -> Result<Vec<u8>, PassError>;
}

impl ViewSource for LightFieldRenderer {
    fn read_view(&mut self, family: FamilyId, view: u32) -> Result<Vec<u8>, PassError> {
        self.read(family, view)
    }
}

/// Views of other ranks by (family, view), over this process's renderer for the others.
pub struct Gathered<'a> {
    pub local: &'a mut LightFieldRenderer,
    pub remote: &'a HashMap<(u32, u32), Vec<u8>>,
    /// The views other ranks rendered: a resource of theirs not sent is one no pass writes.
    pub remote_views: &'a BTreeSet<u32>,
}

impl ViewSource for Gathered<'_> {
    fn read_view(&mut self, family: FamilyId, view: u32) -> Result<Vec<u8>, PassError> {
        if !self.remote_views.contains(&view) {
            return self.local.read(family, view);
        }
        self.remote.get(&(family.0, view)).cloned().ok_or(PassError::MissingOutput { family, view })
    }
}
