//! Typed command-line values shared by the commands: every structured option is parsed by clap
//! (so a bad value is a usage error, exit code 2, naming the flag) into the scene and graph
//! types, and every limit is stated in the message that enforces it.

pub use parallax_render::error::{UsageError, input_error};
use std::ops::RangeInclusive;

use glam::Vec3;
pub use parallax_accuracy::exposure::Exposure;
use parallax_backend::DeviceSelection;
use parallax_graph::{AssignStrategy, LayoutSpec, PartitionError, Scheme};
use parallax_scene::{Camera, Sky, Sun};

/// Most views a light field may have: the presets have 100 and 72; beyond a few thousand the
/// planner's per-view data and every per-view output outgrow what one machine holds.
pub const MAX_VIEWS: u64 = 4096;
/// Most devices (physical or logical) one run may create.
pub const MAX_DEVICES: usize = 64;
/// Largest image width or height accepted before the device is asked (Vulkan guarantees 4096;
/// every current GPU allows 16384 or more, and the device's own limit is checked later).
pub const MAX_IMAGE_SIDE: u32 = 32768;
/// Largest sun irradiance or sky radiance: path throughput × radiance summed over samples must
/// stay finite in f32 on the GPU, where an overflowed sample is dropped.
pub const MAX_RADIANCE: f32 = 1e6;

/// `--scheme`: how a light field's work is split over devices (paper §4.1.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SchemeArg {
    /// Proposed: one set of views per device, its medoid is the source.
    MultiSource,
    /// Tauray: sources in row bands over all devices, the rest on device 0.
    FineSources,
    /// Every view in row bands over all devices, sources all-gathered.
    FineAll,
}

impl From<SchemeArg> for Scheme {
    fn from(s: SchemeArg) -> Scheme {
        match s {
            SchemeArg::MultiSource => Scheme::MultiSource,
            SchemeArg::FineSources => Scheme::FineSources,
            SchemeArg::FineAll => Scheme::FineAll,
        }
    }
}

/// `--assign`: how views are grouped into one set per device (multi-source only).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum AssignArg {
    RoundRobin,
    Contiguous,
    /// Spatially compact balanced bisection (the default of every command).
    #[default]
    Compact,
}

impl From<AssignArg> for AssignStrategy {
    fn from(a: AssignArg) -> AssignStrategy {
        match a {
            AssignArg::RoundRobin => AssignStrategy::RoundRobin,
            AssignArg::Contiguous => AssignStrategy::Contiguous,
            AssignArg::Compact => AssignStrategy::Compact,
        }
    }
}

/// The assignment to plan with. `--assign` only groups views under multi-source; given with a
/// fine scheme it would be silently ignored, so it is refused instead.
pub fn assignment(scheme: SchemeArg, assign: Option<AssignArg>) -> Result<AssignStrategy, UsageError> {
    match (scheme, assign) {
        (SchemeArg::MultiSource, a) => Ok(a.unwrap_or_default().into()),
        (_, None) => Ok(AssignArg::default().into()),
        (s, Some(_)) => Err(UsageError(format!(
            "--assign applies only to --scheme multi-source; --scheme {} places views by row bands: drop --assign",
            Scheme::from(s).name()
        ))),
    }
}

/// `--lf`: a preset or a WxH grid of at most [`MAX_VIEWS`] views.
pub fn parse_layout(s: &str) -> Result<LayoutSpec, String> {
    let spec: LayoutSpec = s.parse().map_err(|e: PartitionError| e.to_string())?;
    if let LayoutSpec::Grid { cols, rows } = spec {
        let views = u64::from(cols) * u64::from(rows);
        if views > MAX_VIEWS {
            return Err(format!("{cols}x{rows} is {views} views; at most {MAX_VIEWS} are supported"));
        }
    }
    Ok(spec)
}

/// `--sources 0,99`: explicit source views of the fine schemes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SourceList(pub Vec<u32>);

pub fn parse_sources(s: &str) -> Result<SourceList, String> {
    parallax_graph::parse_source_list(s).map(SourceList).map_err(|e| e.to_string())
}

/// `--spacing`: a distance in metres, 0..=[`MAX_SPACING`].
pub fn parse_spacing(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if (0.0..=MAX_SPACING).contains(&v) => Ok(v),
        Ok(v) if v.is_finite() && v > MAX_SPACING => Err(format!(
            "{v} m is more than {MAX_SPACING} m between neighbouring views: every view would see something else \
             (light fields space views millimetres to metres apart, e.g. 0.001)"
        )),
        _ => Err(format!("use a finite distance in metres within 0..={MAX_SPACING} (e.g. 0.001)")),
    }
}

/// The widest `--spacing`, in metres.
pub const MAX_SPACING: f64 = 1e3;
/// The range of `--focus`, in metres: nearer than 0.1 mm or farther than 1e9 m the views either
/// disagree everywhere or are identical.
pub const FOCUS_RANGE: std::ops::RangeInclusive<f64> = 1e-4..=1e9;

/// `--focus`: distance of the zero-disparity plane, within [`FOCUS_RANGE`].
pub fn parse_focus(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if FOCUS_RANGE.contains(&v) => Ok(v),
        Ok(v) if v.is_finite() && v > 0.0 => Err(format!(
            "{v} m is outside {:e}..={:e} m: the zero-disparity plane must lie at a distance the views can resolve",
            FOCUS_RANGE.start(),
            FOCUS_RANGE.end()
        )),
        _ => Err(format!(
            "use a finite distance in metres within {:e}..={:e} (e.g. 2.5)",
            FOCUS_RANGE.start(),
            FOCUS_RANGE.end()
        )),
    }
}

/// `--bvh-quality`: obvhs's build presets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BvhQualityArg {
    Fast,
    Medium,
    /// Pre-splits triangles.
    Slow,
    /// Pre-splits triangles.
    VerySlow,
}

impl From<BvhQualityArg> for parallax_scene::BvhQuality {
    fn from(q: BvhQualityArg) -> Self {
        use parallax_scene::BvhQuality as Q;
        match q {
            BvhQualityArg::Fast => Q::Fast,
            BvhQualityArg::Medium => Q::Medium,
            BvhQualityArg::Slow => Q::Slow,
            BvhQualityArg::VerySlow => Q::VerySlow,
        }
    }
}

/// `--dot-detail`: how much of a schedule the DOT drawing shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum DotDetail {
    /// `full` while one pass has at most 40 instances (the drawing's widest row: 8x4 views on
    /// any number of devices), `summary` above (NELF's 72 views drawn in full are 14,800 pt
    /// wide, past reading).
    #[default]
    Auto,
    /// One node per pass and device with instance counts, one per copy kind and device pair.
    Summary,
    /// Every pass instance and copy (large schedules take Graphviz minutes or longer).
    Full,
}

impl From<DotDetail> for parallax_render::compile::DotDetail {
    fn from(d: DotDetail) -> Self {
        match d {
            DotDetail::Auto => Self::Auto,
            DotDetail::Summary => Self::Summary,
            DotDetail::Full => Self::Full,
        }
    }
}

/// `--resolution WxH`, each side 1..=[`MAX_IMAGE_SIDE`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Resolution {
    pub width: u32,
    pub height: u32,
}

impl Resolution {
    pub fn pair(self) -> (u32, u32) {
        (self.width, self.height)
    }
}

pub fn parse_resolution(s: &str) -> Result<Resolution, String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or("expected WxH, e.g. 512x512")?;
    let side = |v: &str, what: &str| -> Result<u32, String> {
        let n: u64 = v.trim().parse().map_err(|_| format!("{what} '{v}' is not a whole number"))?;
        if !(1..=u64::from(MAX_IMAGE_SIDE)).contains(&n) {
            return Err(format!("{what} {n} is outside 1..={MAX_IMAGE_SIDE}"));
        }
        Ok(n as u32)
    };
    Ok(Resolution { width: side(w, "width")?, height: side(h, "height")? })
}

/// Comma-separated finite numbers.
fn floats(s: &str) -> Result<Vec<f32>, String> {
    s.split(',')
        .map(|p| match p.trim().parse::<f32>() {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(_) => Err(format!("'{}' is not finite", p.trim())),
            Err(_) => Err(format!("'{}' is not a number", p.trim())),
        })
        .collect()
}

/// A number as a person would write it back: 5, -1, 1e38.
fn show(v: f32) -> String {
    if v.abs() >= 1e6 { format!("{v:e}") } else { format!("{v}") }
}

/// `--camera eye,target,up,yfov_degrees` (10 numbers). An up vector along the view direction
/// leaves the image's roll undefined, so it is refused rather than silently replaced.
pub fn parse_camera(s: &str) -> Result<Camera, String> {
    let v = floats(s)?;
    if v.len() != 10 {
        return Err(format!("expected 10 numbers eye(3),target(3),up(3),yfov_degrees; got {}", v.len()));
    }
    let eye = Vec3::new(v[0], v[1], v[2]);
    let target = Vec3::new(v[3], v[4], v[5]);
    let up = Vec3::new(v[6], v[7], v[8]);
    // Beyond the scene's coordinate limit the squared distance overflows f32, and a differing
    // eye would be reported as equal to the target.
    for (name, p) in [("eye", eye), ("target", target)] {
        if p.abs().max_element() > parallax_scene::MAX_COORDINATE {
            return Err(format!(
                "{name} coordinate {:e} is beyond ±{:e}, the limit of scene coordinates",
                p.abs().max_element(),
                parallax_scene::MAX_COORDINATE
            ));
        }
    }
    let forward = (target - eye).normalize_or_zero();
    if forward == Vec3::ZERO {
        return Err("eye and target must differ".into());
    }
    if up.normalize_or_zero().cross(forward).length() < 1e-3 {
        return Err("up must be non-zero and not parallel to the view direction (e.g. 0,1,0)".into());
    }
    if !(0.1..179.0).contains(&v[9]) {
        return Err(format!("yfov {} degrees is outside 0.1..179", v[9]));
    }
    Ok(Camera::look_at(eye, target, up, v[9].to_radians()))
}

/// `--camera` with the numbers as given, so that a run file can give them back exactly (the
/// camera's target is not kept by [`Camera`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraArg {
    pub camera: Camera,
    pub numbers: [f32; 10],
}

pub fn parse_camera_arg(s: &str) -> Result<CameraArg, String> {
    let camera = parse_camera(s)?;
    let numbers = floats(s)?.try_into().map_err(|_| "expected 10 numbers".to_string())?;
    Ok(CameraArg { camera, numbers })
}

/// `--sun to_sun_x,to_sun_y,to_sun_z,irradiance[,angular_radius_degrees]`.
pub fn parse_sun(s: &str) -> Result<Sun, String> {
    let v = floats(s)?;
    if v.len() != 4 && v.len() != 5 {
        return Err("expected to_sun_x,to_sun_y,to_sun_z,irradiance[,angular_radius_degrees]".into());
    }
    let dir = Vec3::new(v[0], v[1], v[2]);
    if dir.normalize_or_zero() == Vec3::ZERO {
        return Err("the direction to the sun must be non-zero".into());
    }
    if !(0.0..=MAX_RADIANCE).contains(&v[3]) {
        return Err(format!("irradiance {} is outside 0..={MAX_RADIANCE:e}", show(v[3])));
    }
    let radius = v.get(4).copied().unwrap_or(0.27);
    if !(0.0..=45.0).contains(&radius) {
        return Err(format!("angular radius {radius} degrees is outside 0..=45"));
    }
    Ok(Sun { to_sun: dir.normalize(), irradiance: Vec3::splat(v[3]), angular_radius: radius.to_radians() })
}

/// `--sky r,g,b` (constant) or `zenith_rgb,horizon_rgb,ground_rgb` (gradient, 9 numbers).
pub fn parse_sky(s: &str) -> Result<Sky, String> {
    let v = floats(s)?;
    if let Some(x) = v.iter().find(|x| !(0.0..=MAX_RADIANCE).contains(*x)) {
        return Err(format!("radiance {} is outside 0..={MAX_RADIANCE:e}", show(*x)));
    }
    match v.len() {
        3 => Ok(Sky::Constant(Vec3::new(v[0], v[1], v[2]))),
        9 => Ok(Sky::Gradient {
            zenith: Vec3::new(v[0], v[1], v[2]),
            horizon: Vec3::new(v[3], v[4], v[5]),
            ground: Vec3::new(v[6], v[7], v[8]),
        }),
        n => Err(format!("expected 3 (constant) or 9 (gradient) numbers, got {n}")),
    }
}

/// `--exposure auto|N`: the automatic exposure of the whole light field, or a multiplier in
/// 1e-6..=1e6 (0, negative, NaN or a denormal would write a black image).
pub fn parse_exposure(s: &str) -> Result<Exposure, String> {
    s.parse()
}

/// Which flag of `args` (the command line) was given a value that is not UTF-8, in words: clap
/// says only that some argument was. Paths take any bytes; the flags that take text do not.
pub fn non_utf8_argument(args: impl IntoIterator<Item = std::ffi::OsString>) -> String {
    let mut previous: Option<String> = None;
    for arg in args {
        let Some(text) = arg.to_str() else {
            let bytes = arg.as_encoded_bytes();
            let attached = bytes.starts_with(b"--").then(|| bytes.iter().position(|&b| b == b'=')).flatten();
            let (flag, value) = match (attached, &previous) {
                (Some(at), _) => (String::from_utf8_lossy(&bytes[..at]).into_owned(), &bytes[at + 1..]),
                (None, Some(flag)) if flag.starts_with('-') => (flag.clone(), bytes),
                _ => ("an argument".to_string(), bytes),
            };
            return format!(
                "{flag}: the value '{}' is not UTF-8 text; this flag takes text (only paths may be any bytes)",
                String::from_utf8_lossy(value)
            );
        };
        previous = Some(text.to_string());
    }
    "an argument is not UTF-8 text".to_string()
}

/// The message of `err` if it is a usage error: a [`UsageError`] anywhere in its chain, or a
/// planning error about two flags that do not go together. Errors about the light field (more
/// devices than views, a source listed twice or out of range) stay failures of the run.
pub fn usage_error(err: &anyhow::Error) -> Option<String> {
    err.chain().find_map(|cause| {
        if let Some(usage) = cause.downcast_ref::<UsageError>() {
            return Some(usage.0.clone());
        }
        let plan = cause.downcast_ref::<PartitionError>()?;
        matches!(plan, PartitionError::SourcesWithMultiSource | PartitionError::SourcesPerSetWithFineScheme)
            .then(|| plan.to_string())
    })
}

/// A count within `range`, for clap; the message names the range.
pub fn count_in(range: RangeInclusive<u64>) -> impl Fn(&str) -> Result<u64, String> + Clone {
    move |s: &str| whole_in(s, &range)
}

/// [`count_in`] of a `u32` flag (`render --spp`).
pub fn count_u32_in(range: RangeInclusive<u32>) -> impl Fn(&str) -> Result<u32, String> + Clone {
    move |s: &str| {
        let wide = u64::from(*range.start())..=u64::from(*range.end());
        whole_in(s, &wide).map(|n| n as u32)
    }
}

/// `s` as a whole number within `range`; the message names the range (`nan` included).
fn whole_in(s: &str, range: &RangeInclusive<u64>) -> Result<u64, String> {
    let (lo, hi) = (range.start(), range.end());
    let n: u64 = s.trim().parse().map_err(|_| format!("'{s}' is not a whole number in {lo}..={hi}"))?;
    if range.contains(&n) { Ok(n) } else { Err(format!("{n} is outside {lo}..={hi}")) }
}

/// Which Vulkan devices to use.
#[derive(clap::Args, Debug, Clone)]
pub struct DeviceArgs {
    /// Use N physical GPUs (1..=64).
    #[arg(long, allow_negative_numbers = true, conflicts_with = "fake_devices", value_parser = count_in(1..=MAX_DEVICES as u64))]
    gpus: Option<u64>,
    /// Use N logical devices on one physical device (1..=64; how lavapipe runs multi-device code).
    #[arg(long, allow_negative_numbers = true, value_parser = count_in(1..=MAX_DEVICES as u64))]
    fake_devices: Option<u64>,
}

impl DeviceArgs {
    pub fn selection(&self) -> DeviceSelection {
        selection(self.gpus, self.fake_devices)
    }

    /// `--gpus` and `--fake-devices` as given.
    pub fn given(&self) -> (Option<u64>, Option<u64>) {
        (self.gpus, self.fake_devices)
    }
}

/// `--gpus N` wins over `--fake-devices N`; neither means the first GPU.
pub fn selection(gpus: Option<u64>, fake_devices: Option<u64>) -> DeviceSelection {
    match (gpus, fake_devices) {
        (Some(n), _) => DeviceSelection::Gpus(n as usize),
        (None, Some(n)) => DeviceSelection::FakeDevices(n as usize),
        (None, None) => DeviceSelection::Gpus(1),
    }
}

/// clap value parser of an output: `-` is stdout, anything else a path, UTF-8 or not (as any
/// `PathBuf` flag takes it).
pub fn sink_parser() -> impl clap::builder::TypedValueParser<Value = parallax_render::outputs::Sink> {
    use clap::builder::TypedValueParser as _;
    clap::builder::OsStringValueParser::new().try_map(|s| match s.as_encoded_bytes() {
        b"" => Err("an empty path"),
        b"-" => Ok(parallax_render::outputs::Sink::Stdout),
        _ => Ok(parallax_render::outputs::Sink::File(std::path::PathBuf::from(s))),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_are_capped_with_the_limit_in_the_message() {
        assert_eq!(parse_layout("64x64"), Ok(LayoutSpec::Grid { cols: 64, rows: 64 }));
        assert_eq!(parse_layout("4097x1").unwrap_err(), "4097x1 is 4097 views; at most 4096 are supported");
        assert!(parse_layout("1000000x1000000").unwrap_err().contains("at most 4096"));
    }

    #[test]
    fn resolutions_name_the_bad_side() {
        assert_eq!(parse_resolution("8x4"), Ok(Resolution { width: 8, height: 4 }));
        assert_eq!(parse_resolution("0x10").unwrap_err(), "width 0 is outside 1..=32768");
        assert_eq!(parse_resolution("10x99999").unwrap_err(), "height 99999 is outside 1..=32768");
        assert_eq!(parse_resolution("10").unwrap_err(), "expected WxH, e.g. 512x512");
    }

    #[test]
    fn cameras_refuse_an_up_along_the_view() {
        assert!(parse_camera("0,0,5,0,0,0,0,1,0,45").is_ok());
        assert_eq!(
            parse_camera("0,0,5,0,0,0,0,0,1,45").unwrap_err(),
            "up must be non-zero and not parallel to the view direction (e.g. 0,1,0)"
        );
        assert_eq!(parse_camera("1,1,1,1,1,1,0,1,0,45").unwrap_err(), "eye and target must differ");
        assert_eq!(
            parse_camera("0,0,1e20,0,0,0,0,1,0,45").unwrap_err(),
            "eye coordinate 1e20 is beyond ±1e18, the limit of scene coordinates"
        );
    }

    #[test]
    fn light_values_are_bounded() {
        assert!(parse_sun("0,1,0,5").is_ok());
        assert_eq!(parse_sun("0,1,0,1e38").unwrap_err(), "irradiance 1e38 is outside 0..=1e6");
        assert_eq!(parse_sky("-1,0,0").unwrap_err(), "radiance -1 is outside 0..=1e6");
        assert_eq!(parse_sky("1,NaN,0").unwrap_err(), "'NaN' is not finite");
    }

    #[test]
    fn exposure_must_be_positive_and_finite() {
        assert_eq!(parse_exposure("2"), Ok(Exposure::Fixed(2.0)));
        assert_eq!(parse_exposure("auto"), Ok(Exposure::Auto));
        for bad in ["0", "-1", "NaN", "inf"] {
            assert!(parse_exposure(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn assign_with_a_fine_scheme_is_refused() {
        assert_eq!(assignment(SchemeArg::MultiSource, None).unwrap(), AssignStrategy::Compact);
        assert_eq!(assignment(SchemeArg::FineAll, None).unwrap(), AssignStrategy::Compact);
        assert!(assignment(SchemeArg::FineAll, Some(AssignArg::RoundRobin)).unwrap_err().0.contains("drop --assign"));
    }
}
