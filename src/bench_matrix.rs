//! What `parallax bench` runs: cases (render arguments naming a scene, light field and
//! resolution) crossed with slices of axes, expanded into cells. The cases and slices come from
//! the command line (`--common` and the axis flags: one case, one slice) or from a TOML file
//! (`--matrix FILE.toml`), validated whole before any cell runs:
//!
//! ```toml
//! frames = 20                 # optional: measured frames per cell (default 10)
//! warmup = 5                  # optional: frames before measuring (default 2)
//! [[case]]                    # one or more
//! name = "sponza-multiscopic" # [A-Za-z0-9_-]+, unique: the cells' ids and folders start with it
//! args = "--scene sponza_lite/Sponza.gltf --lf multiscopic --still" # split like a shell
//! reference = "ref/multiscopic" # optional: reference views, relative to this file's folder
//! [[matrix]]                  # one or more slices, each a cartesian product of its axes
//! cases = ["sponza-multiscopic"] # optional: default every case
//! pipelines = ["reproject", "path-trace"]
//! schemes = ["multi-source"]
//! assignments = ["compact"]   # reprojecting multi-source cells only (default: render's)
//! sources_per_set = [1, 2, 4] # reprojecting multi-source cells only
//! spp = [1, 2, 4, 8]
//! denoise = ["on", "off"]     # also "samples": render --denoise samples
//! reprojection_tolerances = [0.05, 0.2, 1.0] # reprojecting cells only (default: render's)
//! devices = [1]
//! fake_devices = false
//! ```
//!
//! Every axis is optional, with the default of its command-line flag. A cell that two slices
//! both produce runs once.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result, anyhow, bail};
use clap::ValueEnum;
use serde::Deserialize;

use crate::options::{AssignArg, SchemeArg};
use crate::pipeline_args::PipelineArg;

/// Cells a bench may run: each is a `render` child of seconds to minutes, and every cell's
/// arguments are held and checked before the first runs.
pub const MAX_CELLS: u64 = 10_000;

/// `--denoise`: SVGF on every view (`on`), over the samples (`samples`: render's `--denoise
/// samples`) or off.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Denoise {
    On,
    Off,
    Samples,
}

/// The command-line spelling of a value of a clap enum.
pub fn name_of<T: ValueEnum>(value: &T) -> String {
    value.to_possible_value().map_or_else(String::new, |v| v.get_name().to_string())
}

pub use parallax_render::bench::case::Case;

/// The axes of one slice.
#[derive(Clone, Debug, PartialEq)]
pub struct Axes {
    pub pipelines: Vec<PipelineArg>,
    pub schemes: Vec<SchemeArg>,
    /// Empty: no `--assign`, render's default.
    pub assignments: Vec<AssignArg>,
    pub sources_per_set: Vec<u32>,
    pub spp: Vec<u32>,
    pub denoise: Vec<Denoise>,
    /// `--reprojection-tolerance` values; empty: render's default (reprojecting cells only).
    pub tolerances: Vec<f64>,
    pub devices: Vec<u32>,
    pub fake_devices: bool,
}

/// The command-line flags' defaults (a test in cmd_bench keeps the two in step).
impl Default for Axes {
    fn default() -> Self {
        Axes {
            pipelines: vec![PipelineArg::Reproject, PipelineArg::PathTrace],
            schemes: vec![SchemeArg::MultiSource],
            assignments: Vec::new(),
            sources_per_set: vec![1],
            spp: vec![1],
            denoise: vec![Denoise::On],
            tolerances: Vec::new(),
            devices: vec![1],
            fake_devices: false,
        }
    }
}

/// Cases crossed with slices.
#[derive(Clone, Debug, PartialEq)]
pub struct Matrix {
    pub frames: Option<u32>,
    pub warmup: Option<u32>,
    pub cases: Vec<Case>,
    /// (indices into `cases`, axes).
    pub slices: Vec<(Vec<usize>, Axes)>,
}

/// One `parallax render` run.
#[derive(Clone, Debug, PartialEq)]
pub struct Cell {
    pub id: String,
    /// Index into [`Matrix::cases`].
    pub case: usize,
    /// Render arguments beyond the case's.
    pub args: Vec<String>,
    pub pipeline: PipelineArg,
    pub scheme: SchemeArg,
    /// Reprojecting multi-source cells: the assignment asked for (None: render's default).
    pub assignment: Option<AssignArg>,
    /// Only reprojecting multi-source cells use more than one.
    pub sources_per_set: u32,
    pub spp: u32,
    pub denoise: Denoise,
    /// Reprojecting cells: the `--reprojection-tolerance` asked for (None: render's default).
    pub tolerance: Option<f64>,
    pub devices: u32,
    pub fake_devices: bool,
}

impl Cell {
    /// Sources per set and the assignment only shape the reprojecting pipeline under
    /// multi-source; other cells run once per remaining axes.
    pub fn shaped(pipeline: PipelineArg, scheme: SchemeArg) -> bool {
        pipeline == PipelineArg::Reproject && scheme == SchemeArg::MultiSource
    }
}

impl Axes {
    /// Cells of one case under these axes, counted from the axis lengths without expanding
    /// them (cells that two slices share are counted in each).
    fn cell_count(&self) -> u64 {
        let len = |n: usize| n.max(1) as u64;
        let mut per_case = 0u64;
        for &pipeline in &self.pipelines {
            for &scheme in &self.schemes {
                let shaped = Cell::shaped(pipeline, scheme);
                let tolerances = if pipeline == PipelineArg::Reproject { len(self.tolerances.len()) } else { 1 };
                let shaping = if shaped { len(self.assignments.len()) * len(self.sources_per_set.len()) } else { 1 };
                per_case = per_case.saturating_add(
                    [shaping, tolerances, len(self.spp.len()), len(self.denoise.len()), len(self.devices.len())]
                        .into_iter()
                        .fold(1u64, u64::saturating_mul),
                );
            }
        }
        per_case
    }

    /// "pipelines 2 × schemes 3 × ... × devices 64": each axis and its length.
    fn lengths(&self) -> String {
        [
            ("pipelines", self.pipelines.len()),
            ("schemes", self.schemes.len()),
            ("assignments", self.assignments.len()),
            ("sources_per_set", self.sources_per_set.len()),
            ("spp", self.spp.len()),
            ("denoise", self.denoise.len()),
            ("reprojection_tolerances", self.tolerances.len()),
            ("devices", self.devices.len()),
        ]
        .iter()
        .filter(|(_, n)| *n > 0)
        .map(|(axis, n)| format!("{axis} {n}"))
        .collect::<Vec<_>>()
        .join(" × ")
    }
}

impl Matrix {
    /// Refuses a matrix of more than [`MAX_CELLS`] cells, counted by multiplying the axis
    /// lengths (no cell is built), naming the largest slice's axes.
    fn check_size(&self) -> Result<()> {
        let counts: Vec<u64> =
            self.slices.iter().map(|(cases, axes)| axes.cell_count().saturating_mul(cases.len() as u64)).collect();
        let total = counts.iter().fold(0u64, |a, &b| a.saturating_add(b));
        if total > MAX_CELLS {
            let (i, count) = counts.iter().enumerate().max_by_key(|(_, c)| **c).expect("a matrix has a slice");
            let (cases, axes) = &self.slices[i];
            bail!(
                "the matrix makes {total} cells, more than the {MAX_CELLS} a bench may run; slice {} alone makes {count} \
                 (cases {} × {}, reprojecting multi-source cells × assignments and sources_per_set, reprojecting \
                 cells × reprojection_tolerances): shorten its longest axes or split the matrix into several benches",
                i + 1,
                cases.len(),
                axes.lengths()
            );
        }
        Ok(())
    }

    /// Every cell, in slice order, each id once. Two cells with one id but different render
    /// arguments (slices differing only in `fake_devices`) would write one folder: refused.
    pub fn cells(&self) -> Result<Vec<Cell>> {
        self.check_size()?;
        let mut out: Vec<Cell> = Vec::new();
        let mut seen: HashMap<String, usize> = HashMap::new();
        for (i, (_, axes)) in self.slices.iter().enumerate() {
            let shaped = axes.pipelines.iter().any(|&p| axes.schemes.iter().any(|&s| Cell::shaped(p, s)));
            if !axes.tolerances.is_empty() && !axes.pipelines.contains(&PipelineArg::Reproject) {
                bail!(
                    "matrix slice {} sets reprojection_tolerances (--reprojection-tolerances), which only shapes \
                     reprojecting cells, and it has none: drop it, or add pipeline reproject",
                    i + 1
                );
            }
            let given =
                [("assignments", !axes.assignments.is_empty()), ("sources_per_set", axes.sources_per_set != [1])];
            if let (false, Some((axis, _))) = (shaped, given.iter().find(|(_, g)| *g)) {
                bail!(
                    "matrix slice {} sets {axis} (--{}), which only shapes reprojecting multi-source cells, \
                     and it has none: drop {axis}, or add pipeline reproject with scheme multi-source",
                    i + 1,
                    axis.replace('_', "-")
                );
            }
        }
        for (cases, axes) in &self.slices {
            for &case in cases {
                for cell in slice_cells(&self.cases[case], case, axes) {
                    match seen.get(&cell.id) {
                        Some(&i) if out[i] == cell => {}
                        Some(_) => bail!(
                            "two matrix slices both make cell {} with different render arguments (fake_devices differs): \
                             put them in separate matrix files",
                            cell.id
                        ),
                        None => {
                            seen.insert(cell.id.clone(), out.len());
                            out.push(cell);
                        }
                    }
                }
            }
        }
        Ok(out)
    }
}

fn slice_cells(case: &Case, case_index: usize, axes: &Axes) -> Vec<Cell> {
    let mut out = Vec::new();
    let prefix = case.name.as_ref().map_or_else(String::new, |n| format!("{n}/"));
    let explicit: Vec<Option<AssignArg>> = axes.assignments.iter().copied().map(Some).collect();
    let given_tolerances: Vec<Option<f64>> = axes.tolerances.iter().copied().map(Some).collect();
    for &pipeline in &axes.pipelines {
        // Only reprojection has a tolerance; other cells run with none.
        let tolerances: &[Option<f64>] = if pipeline == PipelineArg::Reproject && !given_tolerances.is_empty() {
            &given_tolerances
        } else {
            &[None]
        };
        for &scheme in &axes.schemes {
            let shaped = Cell::shaped(pipeline, scheme);
            // Unshaped cells run with render's defaults for both.
            let per_set: &[u32] = if shaped { &axes.sources_per_set } else { &[1] };
            let assignments: &[Option<AssignArg>] = if shaped && !explicit.is_empty() { &explicit } else { &[None] };
            for &assignment in assignments {
                for &sources_per_set in per_set {
                    for &spp in &axes.spp {
                        for &denoise in &axes.denoise {
                            for (&devices, &tolerance) in
                                axes.devices.iter().flat_map(|d| tolerances.iter().map(move |t| (d, t)))
                            {
                                let (p, s, dn) = (name_of(&pipeline), name_of(&scheme), name_of(&denoise));
                                let flag = if axes.fake_devices { "--fake-devices" } else { "--gpus" };
                                let mut args: Vec<String> = vec![
                                    "--pipeline".into(),
                                    p.clone(),
                                    "--scheme".into(),
                                    s.clone(),
                                    "--spp".into(),
                                    spp.to_string(),
                                    flag.into(),
                                    devices.to_string(),
                                ];
                                let mut assign_id = String::new();
                                if let Some(a) = assignment {
                                    args.extend(["--assign".into(), name_of(&a)]);
                                    assign_id = format!("_{}", name_of(&a));
                                }
                                if shaped {
                                    args.extend(["--sources-per-set".into(), sources_per_set.to_string()]);
                                }
                                match denoise {
                                    Denoise::On => {}
                                    Denoise::Off => args.push("--no-denoise".into()),
                                    Denoise::Samples => args.extend(["--denoise".into(), "samples".into()]),
                                }
                                let mut tolerance_id = String::new();
                                if let Some(t) = tolerance {
                                    args.extend(["--reprojection-tolerance".into(), t.to_string()]);
                                    tolerance_id = format!("_tol{t}");
                                }
                                out.push(Cell {
                                    id: format!(
                                        "{prefix}{p}_{s}{assign_id}_k{sources_per_set}_spp{spp}_dn{dn}_d{devices}{tolerance_id}"
                                    ),
                                    case: case_index,
                                    args,
                                    pipeline,
                                    scheme,
                                    assignment,
                                    sources_per_set,
                                    spp,
                                    denoise,
                                    tolerance,
                                    devices,
                                    fake_devices: axes.fake_devices,
                                });
                            }
                        }
                    }
                }
            }
        }
    }
    out
}

/// A clap value enum spelled as on the command line (`"path-trace"`), so the file and the
/// flags accept the same words; a bad word names the allowed ones.
struct Named<T>(T);

impl<'de, T: ValueEnum> Deserialize<'de> for Named<T> {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let word = String::deserialize(d)?;
        T::from_str(&word, false).map(Named).map_err(|_| {
            let allowed: Vec<String> = T::value_variants().iter().map(name_of).collect();
            serde::de::Error::custom(format!("`{word}` is not one of: {}", allowed.join(", ")))
        })
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileToml {
    frames: Option<u32>,
    warmup: Option<u32>,
    #[serde(default)]
    case: Vec<CaseToml>,
    #[serde(default)]
    matrix: Vec<SliceToml>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CaseToml {
    name: String,
    args: String,
    reference: Option<PathBuf>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SliceToml {
    cases: Option<Vec<String>>,
    pipelines: Option<Vec<Named<PipelineArg>>>,
    schemes: Option<Vec<Named<SchemeArg>>>,
    assignments: Option<Vec<Named<AssignArg>>>,
    sources_per_set: Option<Vec<u32>>,
    spp: Option<Vec<u32>>,
    denoise: Option<Vec<Named<Denoise>>>,
    reprojection_tolerances: Option<Vec<f64>>,
    devices: Option<Vec<u32>>,
    fake_devices: Option<bool>,
}

/// Reads and validates a matrix file (module docs); every error names the file, the key and
/// the fix.
pub fn load(path: &Path) -> Result<Matrix> {
    let text = parallax_scene::input::read_text(path, "bench matrix")
        .with_context(|| format!("cannot read --matrix {}", path.display()))?;
    let file = path.display();
    let raw: FileToml = toml::from_str(&text).map_err(|e| {
        anyhow!(
            "--matrix {file}: {}\n(the keys and values are described in `parallax bench --help`)",
            e.to_string().trim_end()
        )
    })?;
    let err = |key: &str, problem: String| anyhow!("--matrix {file}: {key}: {problem}");
    check_range(raw.frames, 1..=100_000).map_err(|p| err("frames", p))?;
    check_range(raw.warmup, 0..=100_000).map_err(|p| err("warmup", p))?;
    if raw.case.is_empty() {
        return Err(err("[[case]]", "there is none: add a [[case]] with `name` and `args`".into()));
    }
    if raw.matrix.is_empty() {
        return Err(err("[[matrix]]", "there is none: add a [[matrix]] (an empty one runs the default axes)".into()));
    }
    let folder = path.parent().unwrap_or(Path::new(""));
    let mut cases: Vec<Case> = Vec::new();
    for (i, c) in raw.case.into_iter().enumerate() {
        let key = format!("[[case]] #{}: name", i + 1);
        if c.name.is_empty() || !c.name.chars().all(|ch| ch.is_ascii_alphanumeric() || ch == '-' || ch == '_') {
            return Err(err(&key, format!("`{}` must be letters, digits, `-` or `_` (it names folders)", c.name)));
        }
        if cases.iter().any(|o| o.name.as_ref() == Some(&c.name)) {
            return Err(err(&key, format!("`{}` names two cases: give each case its own name", c.name)));
        }
        let reference = c.reference.map(|r| folder.join(r));
        if let Some(r) = &reference
            && !r.is_dir()
        {
            return Err(err(
                &format!("[[case]] `{}`: reference", c.name),
                format!(
                    "{} is not a folder: give the reference views' folder (`parallax reference`), relative to {file}'s folder",
                    r.display()
                ),
            ));
        }
        cases.push(Case { name: Some(c.name), args: c.args, reference });
    }
    let mut slices = Vec::new();
    for (i, s) in raw.matrix.into_iter().enumerate() {
        let key = |k: &'static str| format!("[[matrix]] #{}: {k}", i + 1);
        let d = Axes::default();
        let case_indices = match s.cases {
            None => (0..cases.len()).collect(),
            Some(names) => {
                let names = non_empty(names).map_err(|p| err(&key("cases"), p))?;
                names
                    .iter()
                    .map(|n| {
                        cases.iter().position(|c| c.name.as_ref() == Some(n)).ok_or_else(|| {
                            let known: Vec<&str> = cases.iter().filter_map(|c| c.name.as_deref()).collect();
                            err(&key("cases"), format!("no [[case]] is named `{n}`: use one of {}", known.join(", ")))
                        })
                    })
                    .collect::<Result<_>>()?
            }
        };
        let words = |k: &'static str| move |p: String| err(&key(k), p);
        let counts = |v: Option<Vec<u32>>, k: &'static str, range: std::ops::RangeInclusive<u32>, default: Vec<u32>| {
            let v = v.map_or(Ok(default), non_empty).map_err(words(k))?;
            v.iter().try_for_each(|&n| check_range(Some(n), range.clone())).map_err(words(k))?;
            Ok::<_, anyhow::Error>(v)
        };
        let axes = Axes {
            pipelines: axis(s.pipelines, d.pipelines).map_err(words("pipelines"))?,
            schemes: axis(s.schemes, d.schemes).map_err(words("schemes"))?,
            assignments: axis(s.assignments, d.assignments).map_err(words("assignments"))?,
            sources_per_set: counts(s.sources_per_set, "sources_per_set", 1..=64, d.sources_per_set)?,
            spp: counts(s.spp, "spp", 1..=65536, d.spp)?,
            denoise: axis(s.denoise, d.denoise).map_err(words("denoise"))?,
            tolerances: match s.reprojection_tolerances {
                None => d.tolerances,
                Some(v) => non_empty(v)
                    .and_then(|v| v.into_iter().map(crate::pipeline_args::check_reprojection_tolerance).collect())
                    .map_err(words("reprojection_tolerances"))?,
            },
            devices: counts(s.devices, "devices", 1..=64, d.devices)?,
            fake_devices: s.fake_devices.unwrap_or(d.fake_devices),
        };
        slices.push((case_indices, axes));
    }
    Ok(Matrix { frames: raw.frames, warmup: raw.warmup, cases, slices })
}

/// An axis of words: the default when the key is absent, never an empty list.
fn axis<T>(v: Option<Vec<Named<T>>>, default: Vec<T>) -> Result<Vec<T>, String> {
    v.map_or(Ok(default), |v| non_empty(v.into_iter().map(|n| n.0).collect()))
}

fn non_empty<T>(v: Vec<T>) -> Result<Vec<T>, String> {
    if v.is_empty() {
        Err("the list is empty: give at least one value, or leave the key out for its default".into())
    } else {
        Ok(v)
    }
}

fn check_range(v: Option<u32>, range: std::ops::RangeInclusive<u32>) -> Result<(), String> {
    match v {
        Some(n) if !range.contains(&n) => Err(format!("{n} is outside {}..={}", range.start(), range.end())),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load_text(text: &str) -> Result<Matrix> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.toml");
        std::fs::write(&path, text).unwrap();
        load(&path)
    }

    const CASES: &str = "[[case]]\nname = \"a\"\nargs = \"--lf 2x1\"\n[[case]]\nname = \"b\"\nargs = \"--lf 3x1\"\n";

    #[test]
    fn slices_expand_and_repeated_cells_run_once() {
        let m = load_text(&format!(
            "frames = 3\n{CASES}[[matrix]]\ncases = [\"a\"]\npipelines = [\"reproject\"]\nassignments = [\"compact\", \"round-robin\"]\n\
             sources_per_set = [1, 2]\n[[matrix]]\npipelines = [\"reproject\", \"path-trace\"]\nassignments = [\"compact\"]\n"
        ))
        .unwrap();
        assert_eq!(m.frames, Some(3));
        let ids: Vec<String> = m.cells().unwrap().into_iter().map(|c| c.id).collect();
        assert_eq!(
            ids,
            [
                "a/reproject_multi-source_compact_k1_spp1_dnon_d1",
                "a/reproject_multi-source_compact_k2_spp1_dnon_d1",
                "a/reproject_multi-source_round-robin_k1_spp1_dnon_d1",
                "a/reproject_multi-source_round-robin_k2_spp1_dnon_d1",
                "a/path-trace_multi-source_k1_spp1_dnon_d1",
                "b/reproject_multi-source_compact_k1_spp1_dnon_d1",
                "b/path-trace_multi-source_k1_spp1_dnon_d1",
            ]
        );
    }

    #[test]
    fn bad_files_name_the_key() {
        let cases = [
            (format!("{CASES}[[matrix]]\nspps = [1]\n"), "unknown field `spps`"),
            (format!("{CASES}[[matrix]]\npipelines = [\"fast\"]\n"), "`fast` is not one of: reproject, path-trace"),
            (format!("{CASES}[[matrix]]\nspp = []\n"), "[[matrix]] #1: spp: the list is empty"),
            (format!("{CASES}[[matrix]]\ndevices = [65]\n"), "[[matrix]] #1: devices: 65 is outside 1..=64"),
            (format!("{CASES}[[matrix]]\ncases = [\"c\"]\n"), "[[matrix]] #1: cases: no [[case]] is named `c`"),
            (format!("{CASES}{CASES}[[matrix]]\n"), "[[case]] #3: name: `a` names two cases"),
            ("[[case]]\nname = \"a b\"\nargs = \"\"\n[[matrix]]\n".into(), "must be letters, digits"),
            ("[[case]]\nname = \"a\"\nargs = \"\"\nreference = \"nowhere\"\n[[matrix]]\n".into(), "reference: "),
            (CASES.into(), "[[matrix]]: there is none"),
            ("frames = 0\n".into(), "frames: 0 is outside 1..=100000"),
        ];
        for (text, want) in cases {
            let e = load_text(&text).unwrap_err().to_string();
            assert!(e.contains(want) && e.contains("m.toml"), "{text}\n→ {e}");
        }
    }

    #[test]
    fn axes_that_shape_no_cell_of_their_slice_are_refused() {
        let m = load_text(&format!("{CASES}[[matrix]]\npipelines = [\"path-trace\"]\nassignments = [\"compact\"]\n"))
            .unwrap();
        assert!(m.cells().unwrap_err().to_string().contains("matrix slice 1 sets assignments"));
        let m = load_text(&format!("{CASES}[[matrix]]\nschemes = [\"fine-all\"]\nsources_per_set = [2]\n")).unwrap();
        assert!(m.cells().unwrap_err().to_string().contains("sets sources_per_set (--sources-per-set)"));
    }

    #[test]
    fn reprojection_tolerances_shape_only_reprojecting_cells() {
        let m = load_text(&format!(
            "{CASES}[[matrix]]\ncases = [\"a\"]\nreprojection_tolerances = [0.05, 1.0]\nschemes = [\"multi-source\", \"fine-all\"]\n"
        ))
        .unwrap();
        let cells = m.cells().unwrap();
        let ids: Vec<&str> = cells.iter().map(|c| c.id.as_str()).collect();
        assert_eq!(
            ids,
            [
                "a/reproject_multi-source_k1_spp1_dnon_d1_tol0.05",
                "a/reproject_multi-source_k1_spp1_dnon_d1_tol1",
                "a/reproject_fine-all_k1_spp1_dnon_d1_tol0.05",
                "a/reproject_fine-all_k1_spp1_dnon_d1_tol1",
                "a/path-trace_multi-source_k1_spp1_dnon_d1",
                "a/path-trace_fine-all_k1_spp1_dnon_d1",
            ]
        );
        assert!(cells[1].args.ends_with(&["--reprojection-tolerance".into(), "1".into()]));
        assert!(!cells[4].args.iter().any(|a| a == "--reprojection-tolerance"));
        let path_trace_only =
            format!("{CASES}[[matrix]]\npipelines = [\"path-trace\"]\nreprojection_tolerances = [0.1]\n");
        let e = load_text(&path_trace_only).unwrap().cells().unwrap_err().to_string();
        assert!(e.contains("matrix slice 1 sets reprojection_tolerances"), "{e}");
        let negative = load_text(&format!("{CASES}[[matrix]]\nreprojection_tolerances = [-1.0]\n")).unwrap_err();
        assert!(negative.to_string().contains("reprojection_tolerances: -1 is not a relative error"), "{negative}");
    }

    /// 10^7 cells from a few lines of TOML are refused before one is built: counted from the
    /// axis lengths, with the axes named.
    #[test]
    fn matrices_of_more_than_ten_thousand_cells_are_refused_unexpanded() {
        let spp: Vec<String> = (1..=1000).map(|n| n.to_string()).collect();
        let devices: Vec<String> = (1..=64).map(|n| n.to_string()).collect();
        let text = format!(
            "{CASES}[[matrix]]\nassignments = [\"compact\", \"round-robin\"]\nsources_per_set = [1, 2, 4]\n\
             spp = [{}]\ndevices = [{}]\ndenoise = [\"on\", \"off\"]\n",
            spp.join(", "),
            devices.join(", ")
        );
        let m = load_text(&text).unwrap();
        // Per case: reproject 6 × 1000 × 2 × 64 + path-trace 1000 × 2 × 64 = 896,000.
        assert_eq!(m.slices[0].1.cell_count(), 896_000);
        let err = m.cells().unwrap_err().to_string();
        assert_eq!(
            err,
            "the matrix makes 1792000 cells, more than the 10000 a bench may run; slice 1 alone makes 1792000 (cases 2 × \
             pipelines 2 × schemes 1 × assignments 2 × sources_per_set 3 × spp 1000 × denoise 2 × devices 64, \
             reprojecting multi-source cells × assignments and sources_per_set, reprojecting cells × \
             reprojection_tolerances): shorten its longest axes or split the matrix into several benches"
        );
        // The count is exact where no two slices share a cell.
        let small = load_text(&format!("{CASES}[[matrix]]\nspp = [1, 2]\nreprojection_tolerances = [0.1, 0.2, 0.3]\n"))
            .unwrap();
        assert_eq!(small.slices[0].1.cell_count() * 2, small.cells().unwrap().len() as u64);
    }

    #[test]
    fn slices_that_differ_only_in_fake_devices_are_refused() {
        let m = load_text(&format!("{CASES}[[matrix]]\n[[matrix]]\nfake_devices = true\n")).unwrap();
        assert!(m.cells().unwrap_err().to_string().contains("fake_devices differs"));
    }
}
