//! The three partitioning schemes compared in the paper, as placements of one pipeline graph.
//!
//! * `MultiSource` (proposed): views split into N sets, one per device; each set's medoid is its
//!   source; every pass of a view runs whole on its set's device. No copy before the gather.
//! * `FineSources` (Ikkala et al. 2022, Tauray): k sources path traced in row bands over all
//!   devices; everything else runs on device 0, which receives the bands.
//! * `FineAll` (Leria et al. 2024, extended to many views): every view split in bands over all
//!   devices; each device all-gathers the source bands it reprojects from.

use crate::assign::{AssignStrategy, Assignment, assign};
use crate::builder::ViewTopology;
use crate::compile::{PassPlacementInfo, Placement};
use crate::error::PartitionError;
use crate::ids::{DeviceId, Region, ViewId};
use crate::lightfield::LightField;
use crate::scope::Role;
use crate::source::baseline_sources;
use crate::source_cost::{SetPrediction, block_count, cheapest_sources, compact_sources, predict};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Scheme {
    MultiSource,
    FineSources,
    FineAll,
}

impl Scheme {
    pub const ALL: [Scheme; 3] = [Scheme::MultiSource, Scheme::FineSources, Scheme::FineAll];

    pub fn name(self) -> &'static str {
        match self {
            Scheme::MultiSource => "multi-source",
            Scheme::FineSources => "fine-sources",
            Scheme::FineAll => "fine-all",
        }
    }
}

impl std::str::FromStr for Scheme {
    type Err = PartitionError;
    fn from_str(s: &str) -> Result<Self, PartitionError> {
        Scheme::ALL.into_iter().find(|k| k.name() == s).ok_or_else(|| PartitionError::UnknownScheme(s.to_string()))
    }
}

/// What the user chose.
#[derive(Clone, Debug, PartialEq)]
pub struct PartitionConfig {
    pub devices: u32,
    pub scheme: Scheme,
    /// How views are grouped into sets (multi-source).
    pub assign: AssignStrategy,
    /// Explicit sources for the fine-grained schemes; default: k = N placed as in the paper.
    pub sources: Option<Vec<u32>>,
}

/// How many sources each multi-source set has (`--sources-per-set`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SourcesPerSet {
    /// As many, and where, as minimise the predicted frame time (crate::source_cost).
    Auto,
    /// This many in every set, the medoids of its compact split (the paper's k_s).
    Count(u32),
}

/// Sources, sets and placement for one light field, one scheme, N devices.
#[derive(Clone, Debug, PartialEq)]
pub struct Partition {
    pub scheme: Scheme,
    pub devices: u32,
    pub assign: AssignStrategy,
    /// The sets of the multi-source scheme (None for the fine-grained schemes).
    pub assignment: Option<Assignment>,
    pub sources: Vec<ViewId>,
    pub topology: ViewTopology,
    /// Multi-source: whether `--sources-per-set auto` chose the sources, and per set the
    /// prediction of their cost (for a numeric count too); empty under the fine schemes.
    pub sources_auto: bool,
    pub sources_prediction: Vec<SetPrediction>,
}

impl Partition {
    /// The plan of `config` with one source per set (multi-source) or the configured sources.
    pub fn new(lf: &LightField, config: &PartitionConfig) -> Result<Partition, PartitionError> {
        Self::with_sources_per_set(lf, config, 1)
    }

    /// Like [`Partition::new`], with `per_set` sources in every multi-source set (the paper's k_s):
    /// each set is split into `per_set` spatially compact parts whose medoids are the sources,
    /// and every target reprojects from the nearest source of its set.
    pub fn with_sources_per_set(
        lf: &LightField,
        config: &PartitionConfig,
        per_set: u32,
    ) -> Result<Partition, PartitionError> {
        Self::with_sources(lf, config, SourcesPerSet::Count(per_set))
    }

    /// Like [`Partition::with_sources_per_set`], or with each set's sources chosen by their
    /// predicted cost ([`SourcesPerSet::Auto`]).
    pub fn with_sources(
        lf: &LightField,
        config: &PartitionConfig,
        choice: SourcesPerSet,
    ) -> Result<Partition, PartitionError> {
        let per_set = match choice {
            SourcesPerSet::Auto => 1,
            SourcesPerSet::Count(n) => n,
        };
        if per_set == 0 {
            return Err(PartitionError::NoSourcesPerSet);
        }
        if per_set > 1 && config.scheme != Scheme::MultiSource {
            return Err(PartitionError::SourcesPerSetWithFineScheme);
        }
        let m = lf.len() as u32;
        if config.devices == 0 {
            return Err(PartitionError::NoDevices);
        }
        if config.devices > m {
            return Err(PartitionError::MoreDevicesThanViews { devices: config.devices, views: m });
        }
        let mut sources_prediction = Vec::new();
        let (assignment, sources, sources_of) = match config.scheme {
            Scheme::MultiSource => {
                if config.sources.is_some() {
                    return Err(PartitionError::SourcesWithMultiSource);
                }
                let a = assign(config.assign, &lf.positions, config.devices)?;
                let smallest = a.sets.iter().map(Vec::len).min().unwrap_or(0) as u32;
                if per_set > smallest {
                    return Err(PartitionError::TooManySourcesPerSet { per_set, smallest });
                }
                let mut set_sources: Vec<Vec<ViewId>> = Vec::new();
                for (i, set) in a.sets.iter().enumerate() {
                    let (chosen, prediction) = match choice {
                        SourcesPerSet::Auto => cheapest_sources(lf, i as u32, set)?,
                        SourcesPerSet::Count(n) => {
                            let chosen = compact_sources(lf, set, n)?;
                            let prediction = predict(lf, i as u32, set, &chosen, block_count(lf, set));
                            (chosen, prediction)
                        }
                    };
                    set_sources.push(chosen);
                    sources_prediction.push(prediction);
                }
                let sources_of = (0..m)
                    .map(|v| {
                        let own = &set_sources[a.set_of_view[v as usize] as usize];
                        if own.contains(&ViewId(v)) {
                            Vec::new()
                        } else {
                            nearest_first(lf, ViewId(v), own)[..1].to_vec()
                        }
                    })
                    .collect();
                let mut sources: Vec<ViewId> = set_sources.into_iter().flatten().collect();
                sources.sort();
                (Some(a), sources, sources_of)
            }
            Scheme::FineSources | Scheme::FineAll => {
                let sources = match &config.sources {
                    Some(list) => checked_sources(list, m)?,
                    None => baseline_sources(&lf.positions, lf.centre(), config.devices as usize),
                };
                // Every target reads every source, nearest first: the kernel tries them in this
                // order, so a pixel one source cannot see may still come from another.
                let sources_of =
                    (0..m)
                        .map(|v| {
                            if sources.contains(&ViewId(v)) {
                                Vec::new()
                            } else {
                                nearest_first(lf, ViewId(v), &sources)
                            }
                        })
                        .collect();
                (None, sources, sources_of)
            }
        };
        let is_source = (0..m).map(|v| sources.contains(&ViewId(v))).collect();
        let topology = ViewTopology { width: lf.width, height: lf.height, sources_of, is_source };
        Ok(Partition {
            scheme: config.scheme,
            devices: config.devices,
            assign: config.assign,
            assignment,
            sources,
            topology,
            sources_auto: choice == SourcesPerSet::Auto && config.scheme == Scheme::MultiSource,
            sources_prediction,
        })
    }

    /// Device of each view's set under multi-source.
    pub fn set_of_view(&self) -> Option<&[u32]> {
        self.assignment.as_ref().map(|a| a.set_of_view.as_slice())
    }

    fn bands(&self, height: u32) -> Vec<(DeviceId, Region)> {
        Region::bands(height, self.devices)
            .into_iter()
            .enumerate()
            .filter(|(_, r)| !r.is_empty())
            .map(|(d, r)| (DeviceId(d as u32), r))
            .collect()
    }
}

/// `sources` ordered by distance to `target` on the camera plane (ties by view index).
fn nearest_first(lf: &LightField, target: ViewId, sources: &[ViewId]) -> Vec<ViewId> {
    let at = lf.position(target);
    let mut ordered = sources.to_vec();
    ordered.sort_by(|&a, &b| {
        at.distance_squared(lf.position(a)).total_cmp(&at.distance_squared(lf.position(b))).then(a.cmp(&b))
    });
    ordered
}

impl Placement for Partition {
    fn devices(&self) -> u32 {
        self.devices
    }

    fn place(&self, pass: PassPlacementInfo<'_>, view: ViewId, height: u32) -> Vec<(DeviceId, Region)> {
        let whole = |d: u32| vec![(DeviceId(d), Region::rows(height))];
        match self.scheme {
            Scheme::MultiSource => whole(self.set_of_view().expect("multi-source has sets")[view.index()]),
            Scheme::FineSources if pass.splittable && pass.role == Role::Sources => self.bands(height),
            Scheme::FineAll if pass.splittable => self.bands(height),
            Scheme::FineSources | Scheme::FineAll => whole(0),
        }
    }
}

/// Parses `--sources 0,99`.
pub fn parse_source_list(s: &str) -> Result<Vec<u32>, PartitionError> {
    if s.trim().is_empty() {
        return Err(PartitionError::NoSources);
    }
    s.split(',').map(|t| t.trim().parse::<u32>().map_err(|_| PartitionError::BadSourceList(s.to_string()))).collect()
}

fn checked_sources(list: &[u32], views: u32) -> Result<Vec<ViewId>, PartitionError> {
    if list.is_empty() {
        return Err(PartitionError::NoSources);
    }
    let mut seen = std::collections::BTreeSet::new();
    for &v in list {
        if v >= views {
            return Err(PartitionError::SourceOutOfRange { view: v, views });
        }
        if !seen.insert(v) {
            return Err(PartitionError::DuplicateSource(v));
        }
    }
    if seen.len() as u32 == views {
        return Err(PartitionError::AllViewsSources { sources: views, views });
    }
    Ok(seen.into_iter().map(ViewId).collect())
}
