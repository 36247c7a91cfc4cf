//! Light-field layouts: where the views sit on the (s,t) plane and how each view's pinhole
//! camera is derived from one rig camera.
//!
//! Views are one 1D array, row-major over the whole grid (`index = row * cols + col`), which is
//! how the paper indexes them. Positions are in metres in the rig's (right, up) plane, centred on
//! the rig eye. Every view looks along the rig's forward axis; its frustum is shifted (off-axis
//! pan) so that the zero-disparity plane, at `focus_distance` in front of the rig, lands on the
//! same pixels in every view.

use glam::{DVec2, DVec3};

use crate::error::PartitionError;
use crate::ids::ViewId;

/// A light field: view positions, per-view resolution and the rig every camera derives from.
#[derive(Clone, Debug, PartialEq)]
pub struct LightField {
    /// Short name used in reports ("multiscopic", "nelf", "8x4").
    pub name: String,
    /// Grid columns (views per row).
    pub cols: u32,
    /// Grid rows.
    pub rows: u32,
    /// Per-view image width in pixels.
    pub width: u32,
    /// Per-view image height in pixels.
    pub height: u32,
    /// Position of each view on the (s,t) plane, metres, row-major.
    pub positions: Vec<DVec2>,
    /// The camera the grid is laid out around.
    pub rig: Rig,
}

/// The centre camera of a light field. View cameras are this camera translated in its
/// (right, up) plane and panned off-axis toward the zero-disparity plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rig {
    pub eye: DVec3,
    pub forward: DVec3,
    pub up: DVec3,
    /// Vertical field of view in radians.
    pub yfov: f64,
    /// Distance of the zero-disparity plane from the rig eye along `forward`, metres.
    pub focus_distance: f64,
}

impl Default for Rig {
    fn default() -> Self {
        Rig {
            eye: DVec3::new(0.0, 1.0, 4.0),
            forward: DVec3::NEG_Z,
            up: DVec3::Y,
            yfov: 45f64.to_radians(),
            focus_distance: 4.0,
        }
    }
}

/// One view's pinhole camera, ready for a renderer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewCamera {
    pub eye: DVec3,
    pub forward: DVec3,
    pub right: DVec3,
    pub up: DVec3,
    pub yfov: f64,
    pub aspect: f64,
    /// Off-axis shift of the image centre in NDC units ([-1, 1] spans the image).
    pub ndc_shift: DVec2,
}

impl ViewCamera {
    /// Projects a world point to NDC (x right, y up; [-1, 1] spans the image). None when the
    /// point is not in front of the camera. NDC = perspective divide + `ndc_shift`.
    pub fn project(&self, world: DVec3) -> Option<DVec2> {
        let d = world - self.eye;
        let z = d.dot(self.forward);
        if z <= 0.0 {
            return None;
        }
        let tan = (self.yfov * 0.5).tan();
        let ndc = DVec2::new(d.dot(self.right) / (z * tan * self.aspect), d.dot(self.up) / (z * tan));
        Some(ndc + self.ndc_shift)
    }

    /// Direction of the primary ray through NDC point `ndc` (inverse of [`ViewCamera::project`]).
    pub fn ray_direction(&self, ndc: DVec2) -> DVec3 {
        let tan = (self.yfov * 0.5).tan();
        let p = ndc - self.ndc_shift;
        (self.forward + self.right * (p.x * tan * self.aspect) + self.up * (p.y * tan)).normalize()
    }
}

/// Which preset or grid the user asked for (parsed from `--lf`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LayoutSpec {
    /// 100×1 views, 768×432 each, 1 mm apart (paper §4.1.2).
    Multiscopic,
    /// 12×6 views: two 6×6 blocks 62 mm apart, 1 mm inside a block, 1024×1024 each.
    Nelf,
    /// Any W×H grid.
    Grid { cols: u32, rows: u32 },
}

impl std::str::FromStr for LayoutSpec {
    type Err = PartitionError;
    fn from_str(s: &str) -> Result<Self, PartitionError> {
        match s {
            "multiscopic" => Ok(LayoutSpec::Multiscopic),
            "nelf" => Ok(LayoutSpec::Nelf),
            _ => {
                let (cols, rows) = parse_pair(s).ok_or_else(|| PartitionError::BadLayout(s.to_string()))?;
                if cols == 0 || rows == 0 {
                    return Err(PartitionError::EmptyLayout { cols, rows });
                }
                Ok(LayoutSpec::Grid { cols, rows })
            }
        }
    }
}

/// Parses "WxH" into two integers.
pub fn parse_pair(s: &str) -> Option<(u32, u32)> {
    let (a, b) = s.split_once(['x', 'X'])?;
    Some((a.trim().parse().ok()?, b.trim().parse().ok()?))
}

/// Default spacing between neighbouring views (paper §4.1.2: 1 mm).
pub const DEFAULT_SPACING: f64 = 0.001;
/// Distance between the two eye blocks of the NELF preset (interpupillary distance).
pub const NELF_EYE_SEPARATION: f64 = 0.062;

impl LightField {
    /// Builds a layout. `spacing` and `resolution` override the preset's values when given.
    pub fn new(
        spec: LayoutSpec,
        spacing: Option<f64>,
        resolution: Option<(u32, u32)>,
        rig: Rig,
    ) -> Result<Self, PartitionError> {
        if let Some(d) = spacing
            && (!d.is_finite() || d < 0.0)
        {
            return Err(PartitionError::BadSpacing(d));
        }
        if let Some((w, h)) = resolution
            && (w == 0 || h == 0)
        {
            return Err(PartitionError::BadResolution { width: w, height: h });
        }
        if !(rig.focus_distance.is_finite() && rig.focus_distance > 0.0) {
            return Err(PartitionError::BadFocus(rig.focus_distance));
        }
        let d = spacing.unwrap_or(DEFAULT_SPACING);
        let (name, cols, rows, default_res, positions) = match spec {
            LayoutSpec::Multiscopic => ("multiscopic".into(), 100, 1, (768, 432), grid(100, 1, d)),
            LayoutSpec::Nelf => ("nelf".into(), 12, 6, (1024, 1024), nelf(d)),
            LayoutSpec::Grid { cols, rows } => {
                if cols == 0 || rows == 0 {
                    return Err(PartitionError::EmptyLayout { cols, rows });
                }
                (format!("{cols}x{rows}"), cols, rows, (512, 512), grid(cols, rows, d))
            }
        };
        let (width, height) = resolution.unwrap_or(default_res);
        Ok(LightField { name, cols, rows, width, height, positions, rig })
    }

    /// Number of views M.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    pub fn views(&self) -> impl Iterator<Item = ViewId> + '_ {
        (0..self.len() as u32).map(ViewId)
    }

    pub fn position(&self, v: ViewId) -> DVec2 {
        self.positions[v.index()]
    }

    /// Centre of the bounding box of all view positions.
    pub fn centre(&self) -> DVec2 {
        let (lo, hi) = self
            .positions
            .iter()
            .fold((DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)), |(lo, hi), p| {
                (lo.min(*p), hi.max(*p))
            });
        (lo + hi) * 0.5
    }

    /// The pinhole camera of view `v`.
    pub fn camera(&self, v: ViewId) -> ViewCamera {
        let forward = self.rig.forward.normalize();
        let right = forward.cross(self.rig.up).normalize();
        let up = right.cross(forward);
        let p = self.position(v);
        let aspect = self.width as f64 / self.height as f64;
        let half_h = (self.rig.yfov * 0.5).tan() * self.rig.focus_distance;
        let half_w = half_h * aspect;
        // Seen from this view, the rig-axis point on the focus plane is offset by -p; shifting
        // the image by +p (in NDC at that depth) puts it at the centre in every view, so the
        // whole focus plane has zero disparity.
        let ndc_shift = DVec2::new(p.x / half_w, p.y / half_h);
        ViewCamera {
            eye: self.rig.eye + right * p.x + up * p.y,
            forward,
            right,
            up,
            yfov: self.rig.yfov,
            aspect,
            ndc_shift,
        }
    }
}

/// A W×H grid centred on the origin; row 0 is the top row (largest t).
fn grid(cols: u32, rows: u32, d: f64) -> Vec<DVec2> {
    let (cx, cy) = ((cols as f64 - 1.0) * 0.5, (rows as f64 - 1.0) * 0.5);
    (0..rows).flat_map(|r| (0..cols).map(move |c| DVec2::new((c as f64 - cx) * d, (cy - r as f64) * d))).collect()
}

/// Two 6×6 blocks side by side: columns 0–5 are the left eye, 6–11 the right eye.
fn nelf(d: f64) -> Vec<DVec2> {
    let block = grid(6, 6, d);
    let half = NELF_EYE_SEPARATION * 0.5;
    (0..6)
        .flat_map(|r| {
            let block = &block;
            (0..12).map(move |c| {
                let p = block[(r * 6 + c % 6) as usize];
                let eye = if c < 6 { -half } else { half };
                DVec2::new(p.x + eye, p.y)
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_match_the_paper() {
        let m = LightField::new(LayoutSpec::Multiscopic, None, None, Rig::default()).unwrap();
        assert_eq!((m.len(), m.width, m.height), (100, 768, 432));
        assert!((m.positions[1].x - m.positions[0].x - 0.001).abs() < 1e-12);
        let n = LightField::new(LayoutSpec::Nelf, None, None, Rig::default()).unwrap();
        assert_eq!((n.len(), n.width, n.height), (72, 1024, 1024));
        // Block centres 62 mm apart; 1 mm inside a block; row-major indexing over 12 columns.
        let left: f64 = (0..6).map(|c| n.positions[c].x).sum::<f64>() / 6.0;
        let right: f64 = (6..12).map(|c| n.positions[c].x).sum::<f64>() / 6.0;
        assert!((right - left - 0.062).abs() < 1e-12);
        assert!((n.positions[1].x - n.positions[0].x - 0.001).abs() < 1e-12);
        assert!((n.positions[0].y - n.positions[12].y - 0.001).abs() < 1e-12);
    }

    #[test]
    fn focus_plane_has_zero_disparity() {
        let rig = Rig { focus_distance: 2.5, ..Rig::default() };
        let lf = LightField::new(LayoutSpec::Grid { cols: 5, rows: 3 }, Some(0.05), Some((64, 32)), rig).unwrap();
        let on_plane = rig.eye + rig.forward * 2.5 + DVec3::new(0.3, -0.2, 0.0);
        let off_plane = rig.eye + rig.forward * 6.0;
        let first = lf.camera(ViewId(0)).project(on_plane).unwrap();
        let far0 = lf.camera(ViewId(0)).project(off_plane).unwrap();
        for v in lf.views() {
            let ndc = lf.camera(v).project(on_plane).unwrap();
            assert!((ndc - first).length() < 1e-9, "view {v:?}: {ndc} vs {first}");
        }
        let far_last = lf.camera(ViewId(14)).project(off_plane).unwrap();
        assert!((far_last - far0).length() > 1e-3, "points off the focus plane must show parallax");
    }

    #[test]
    fn bad_layouts_are_rejected() {
        assert_eq!("0x3".parse::<LayoutSpec>(), Err(PartitionError::EmptyLayout { cols: 0, rows: 3 }));
        assert_eq!("banana".parse::<LayoutSpec>(), Err(PartitionError::BadLayout("banana".into())));
        let spec = LayoutSpec::Grid { cols: 2, rows: 2 };
        let err = LightField::new(spec, Some(f64::NAN), None, Rig::default()).unwrap_err();
        assert!(matches!(err, PartitionError::BadSpacing(d) if d.is_nan()));
        let err = LightField::new(spec, Some(-1.0), None, Rig::default()).unwrap_err();
        assert_eq!(err, PartitionError::BadSpacing(-1.0));
    }
}
