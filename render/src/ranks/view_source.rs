//! Where the outputs read a finished view from: the renderer of this process, or (rank 0 of a
//! render over several ranks) the views other ranks sent, with its own renderer for the rest;
//! under a fine scheme its renderer with the bands other ranks sent of layers not gathered.

use std::collections::{BTreeSet, HashMap};

use parallax_backend::remote_device;
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
    /// Under a fine scheme, the bands of layers left on other ranks' devices (not gathered to
    /// device 0), by (family, view, global device): whole-view images whose band rows are theirs.
    pub bands: &'a HashMap<(u32, u32, u32), Vec<u8>>,
}

impl ViewSource for Gathered<'_> {
    fn read_view(&mut self, family: FamilyId, view: u32) -> Result<Vec<u8>, PassError> {
        if self.remote_views.contains(&view) {
            return self.remote.get(&(family.0, view)).cloned().ok_or(PassError::MissingOutput { family, view });
        }
        let plan = self.local.plan();
        let here = plan.devices.len();
        let bands = plan.final_bands(family, view).unwrap_or_default();
        if bands.iter().all(|(device, ..)| remote_device(here, *device).is_none()) {
            return self.local.read(family, view);
        }
        // Bands on this process's devices from its renderer, the others from their ranks.
        let desc = plan.resource(bands[0].1);
        let row_bytes = desc.row_bytes() as usize;
        let mut out = vec![0u8; row_bytes * desc.height as usize];
        for (device, resource, rows) in bands {
            let bytes = match remote_device(here, device) {
                Some(global) => self
                    .bands
                    .get(&(family.0, view, global))
                    .cloned()
                    .ok_or(PassError::MissingOutput { family, view })?,
                None => self.local.executor().read_resource(device, resource)?,
            };
            let rows = rows.y0 as usize * row_bytes..rows.y1 as usize * row_bytes;
            out[rows.clone()].copy_from_slice(&bytes[rows]);
        }
        Ok(out)
    }
}
