//! Scoring: every row of every frame against the spec, pooled and per frame, by range, with the three-state shares.

use super::*;

/// One configuration's scores on one frame or pooled over frames.
#[derive(Debug, Clone, Serialize)]
pub struct RealRow {
    /// `mode:label`, as in `tre eval`.
    pub key: String,
    /// Over every pixel with spec roughness.
    pub all: ScoreMetrics,
    /// Per range bin (sensor depth).
    pub by_range: BTreeMap<String, ScoreMetrics>,
    /// Roughness inside the floor box, when there is one.
    pub floor: Option<FloorStats>,
    /// Depth errors against the sensor (`rgb` mode only).
    pub depth: Option<DepthMetrics>,
    /// The three-state map under the sensor's noise model (modes that read sensor depth),
    /// or the mode's calibrated intervals.
    pub traversal: Option<TraversalMetrics>,
    /// Missed hazards, floor coverage and interval coverage of the three-state map.
    pub safety: Option<Safety>,
    /// Wall time per stage, ms (mean per frame when pooled).
    pub ms: BTreeMap<String, f64>,
}

/// The median of `values` (NaN for none).
pub(super) fn median(mut values: Vec<f64>) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mid = values.len() / 2;
    *values.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// The spec on one frame, or pooled.
#[derive(Debug, Clone, Serialize)]
pub struct SpecSummary {
    /// Roughness inside the floor box, when there is one.
    pub floor: Option<FloorStats>,
    /// Pixels with depth.
    pub valid_px: usize,
    /// Boundary pixels.
    pub boundary_px: usize,
    /// Pixels at or above the hazard threshold.
    pub hazard_px: usize,
    /// Time of `annotate` on the frame, ms (mean when pooled).
    pub ms: f64,
}

/// One frame's results.
#[derive(Debug, Clone, Serialize)]
pub struct FrameReport {
    /// `sequence/depth`.
    pub name: String,
    /// The RGB file.
    pub rgb: PathBuf,
    /// The depth file.
    pub depth: PathBuf,
    /// `(width, height)`.
    pub size: (usize, usize),
    /// The floor box, if any.
    pub floor_box: Option<[usize; 4]>,
    /// The spec on the sensor depth.
    pub spec: SpecSummary,
    /// Each configuration.
    pub rows: Vec<RealRow>,
}

/// The whole report (`--json`).
#[derive(Debug, Clone, Serialize)]
pub struct RealReport {
    /// The folders scored.
    pub data: Vec<PathBuf>,
    /// The split scored (`--real-splits`), if any.
    pub split: Option<String>,
    /// What the modes are scored against.
    pub reference: Reference,
    /// Whether the cameras' stated mountings were left out (`--no-mounting`).
    pub mounting_ignored: bool,
    /// Frames scored.
    pub frames: usize,
    /// Hazard threshold, metres.
    pub hazard_m: f64,
    /// Flat threshold of the false-hazard rate, metres.
    pub flat_m: f64,
    /// Range bins: `(name, from_m, to_m)`.
    pub range_bins: Vec<(String, f64, f64)>,
    /// The spec pooled over frames.
    pub spec: SpecSummary,
    /// Each configuration pooled over frames (pixels pooled).
    pub pooled: Vec<RealRow>,
    /// Each configuration pooled over the frames of each sequence folder.
    pub per_sequence: BTreeMap<String, Vec<RealRow>>,
    /// Each frame.
    pub per_frame: Vec<FrameReport>,
}

/// The configurations scored: the learned modes asked for with `base`'s switches, and the
/// geometric mode as the terrain estimate (its default), the spec, the paper's surface-only
/// baseline and the spec on cleaned depth, in that order; slope is left out of traversability
/// (the frames' mountings are unknown).
pub fn real_rows(modes: &[Mode], base: &PipelineConfig) -> Vec<(String, PipelineConfig)> {
    // The frames' mountings are unknown, so slope (which needs the pitch) does not count:
    // the three-state map judges roughness and noise alone.
    let base = &PipelineConfig {
        traversability: tre_pipeline::Traversability {
            max_slope_rad: std::f64::consts::FRAC_PI_2,
            ..base.traversability
        },
        ..*base
    };
    let mut cfgs = Vec::new();
    for &mode in modes {
        if mode == Mode::Geometric {
            for geometric in [
                GeometricMethod::Terrain,
                GeometricMethod::Spec,
                GeometricMethod::SurfaceOnly,
                GeometricMethod::SpecCleaned,
            ] {
                cfgs.push(PipelineConfig {
                    mode,
                    geometric,
                    ..*base
                });
            }
        } else {
            cfgs.push(PipelineConfig { mode, ..*base });
        }
    }
    cfgs.into_iter()
        .map(|c| (crate::synthetic::row_key(&c), c))
        .collect()
}

/// Accumulators of one configuration.
#[derive(Default)]
pub(super) struct RowAcc {
    scores: RangeScores,
    floor: Vec<f64>,
    floor_missing: usize,
    depth: DepthAccumulator,
    has_depth: bool,
    traversal: Option<TraversalAcc>,
    safety: Option<SafetyAcc>,
    ms: BTreeMap<String, f64>,
}

impl RowAcc {
    fn finish(&self, key: &str, frames: usize, has_floor: bool) -> RealRow {
        let n = frames.max(1) as f64;
        RealRow {
            key: key.to_owned(),
            all: self.scores.all.finish(),
            by_range: RANGE_BINS
                .iter()
                .zip(&self.scores.by_range)
                .map(|(&(name, _, _), s)| (name.to_owned(), s.finish()))
                .collect(),
            floor: has_floor.then(|| floor_stats(self.floor.clone(), self.floor_missing)),
            depth: self.has_depth.then(|| self.depth.finish()),
            traversal: self.traversal.as_ref().map(|t| t.finish(has_floor)),
            safety: self.safety.as_ref().map(SafetyAcc::finish),
            ms: self.ms.iter().map(|(k, v)| (k.clone(), v / n)).collect(),
        }
    }

    fn merge(&mut self, other: &Self) {
        self.scores.merge(&other.scores);
        self.floor.extend_from_slice(&other.floor);
        self.floor_missing += other.floor_missing;
        self.depth.merge(&other.depth);
        self.has_depth |= other.has_depth;
        if let Some(t) = &other.traversal {
            self.traversal.get_or_insert_with(Default::default).merge(t);
        }
        if let Some(t) = &other.safety {
            self.safety.get_or_insert_with(Default::default).merge(t);
        }
        for (k, v) in &other.ms {
            *self.ms.entry(k.clone()).or_default() += v;
        }
    }
}

/// [`RANGE_BINS`] as the report writes them.
fn range_bins() -> Vec<(String, f64, f64)> {
    RANGE_BINS
        .iter()
        .map(|&(name, a, b)| (name.to_owned(), a, b))
        .collect()
}

/// A frame read with its sensor's noise model, its spec on `reference`'s depth, and its pose;
/// `None` (and a log line) when the reference has none for it.
fn load_referenced(
    frame: &RealFrame,
    (frames, reference): (&[RealFrame], Reference),
    sensor: &SensorNoise,
) -> Result<Option<(LoadedFrame, Option<Pose>)>, BenchError> {
    let load = || -> Result<_, FrameLoadError> {
        let raw = load_frame(frame)?.sensed(frame, sensor);
        let Some(loaded) = reference.apply(frame, frames, &FuseConfig::default(), raw)? else {
            return Ok(None);
        };
        Ok(Some((loaded, Pose::of(frame)?)))
    };
    let loaded = load().map_err(|source| BenchError::Load {
        frame: frame.name(),
        source: Box::new(source),
    })?;
    if loaded.is_none() {
        tracing::info!(
            "{}: no pose or neighbour, left out of the reference",
            frame.name()
        );
    }
    Ok(loaded)
}

/// Runs the benchmark: every frame, every configuration; the modes that read sensor depth also
/// get the uncertainty and three-state maps under `sensor`'s noise model (or the frame's camera
/// file's, when it names one). Calls `on_frame` with each frame's maps (for the contact
/// sheets) once it is scored.
///
/// # Errors
///
/// When a frame does not read, a configuration fails on it or `on_frame` fails.
pub fn run_benchmark(
    (data, split): (&[PathBuf], Option<&str>),
    (frames, reference): (&[RealFrame], Reference),
    floors: &Floors,
    rows: &[(String, PipelineConfig)],
    pipeline: &mut Pipeline,
    sensor: &SensorNoise,
    mut on_frame: impl FnMut(&RealFrame, &LoadedFrame, &[RowMaps]) -> Result<(), io::IoError>,
) -> Result<RealReport, BenchError> {
    let mut pooled = fresh(rows);
    let mut per_sequence: BTreeMap<String, (usize, Vec<RowAcc>)> = BTreeMap::new();
    let mut spec_acc = SpecAcc::default();
    let mut per_frame = Vec::new();
    let key = |f: &RealFrame| (f.sequence.clone(), f.depth_rel.clone());
    let any_floor = frames.iter().any(|f| floors.contains_key(&key(f)));
    let mut prev: Option<PrevView> = None;
    for (i, frame) in frames.iter().enumerate() {
        let Some((loaded, pose)) = load_referenced(frame, (frames, reference), sensor)? else {
            continue;
        };
        let other = shared_with(prev.as_ref(), frame, pose, &loaded);
        let floor_box = floors.get(&key(frame)).copied();
        let spec = spec_summary(&loaded, floor_box);
        spec_acc.add(&spec, &loaded, floor_box);
        let scored = FrameScoring {
            frame,
            loaded: &loaded,
            floor_box,
            sensor: frame_sensor(frame, sensor),
            other: other.as_ref(),
        };
        let seq = per_sequence
            .entry(frame.sequence.clone())
            .or_insert_with(|| (0, fresh(rows)));
        seq.0 += 1;
        let (reports, maps) = scored.score(pipeline, rows, [&mut pooled, &mut seq.1])?;
        on_frame(frame, &loaded, &maps).map_err(BenchError::Sheet)?;
        per_frame.push(FrameReport {
            name: frame.name(),
            rgb: frame.rgb.clone(),
            depth: frame.depth.clone(),
            size: loaded.spec.roughness_m.size(),
            floor_box,
            spec,
            rows: reports,
        });
        tracing::info!("{}/{} frames: {}", i + 1, frames.len(), frame.name());
        prev = pose.map(|pose| PrevView::new(frame, pose, loaded));
    }
    let n = per_frame.len();
    Ok(RealReport {
        data: data.to_owned(),
        split: split.map(str::to_owned),
        reference,
        mounting_ignored: false,
        frames: n,
        hazard_m: HAZARD_M,
        flat_m: FLAT_M,
        range_bins: range_bins(),
        spec: spec_acc.finish(any_floor, n),
        pooled: rows
            .iter()
            .zip(&pooled)
            .map(|((key, _), acc)| acc.finish(key, n, any_floor))
            .collect(),
        per_sequence: finish_sequences(per_sequence, rows, any_floor),
        per_frame,
    })
}

/// The spec's own figures summed over the frames.
#[derive(Default)]
struct SpecAcc {
    floor: Vec<f64>,
    floor_missing: usize,
    valid_px: usize,
    boundary_px: usize,
    hazard_px: usize,
    ms: f64,
}

impl SpecAcc {
    /// Adds a frame's figures, and the spec's values in its floor box if it has one.
    fn add(&mut self, spec: &SpecSummary, loaded: &LoadedFrame, floor_box: Option<[usize; 4]>) {
        if let Some(b) = floor_box {
            let (v, m) = box_values(&loaded.spec.roughness_m, b);
            self.floor.extend(v);
            self.floor_missing += m;
        }
        self.valid_px += spec.valid_px;
        self.boundary_px += spec.boundary_px;
        self.hazard_px += spec.hazard_px;
        self.ms += spec.ms;
    }

    /// The figures pooled over `frames` frames (with floor statistics when any had a box).
    fn finish(self, any_floor: bool, frames: usize) -> SpecSummary {
        SpecSummary {
            floor: any_floor.then(|| floor_stats(self.floor, self.floor_missing)),
            valid_px: self.valid_px,
            boundary_px: self.boundary_px,
            hazard_px: self.hazard_px,
            ms: self.ms / frames.max(1) as f64,
        }
    }
}

/// One empty accumulator per row.
fn fresh(rows: &[(String, PipelineConfig)]) -> Vec<RowAcc> {
    rows.iter().map(|_| RowAcc::default()).collect()
}

/// Each sequence's rows, from its frame count and accumulators.
fn finish_sequences(
    per_sequence: BTreeMap<String, (usize, Vec<RowAcc>)>,
    rows: &[(String, PipelineConfig)],
    any_floor: bool,
) -> BTreeMap<String, Vec<RealRow>> {
    per_sequence
        .into_iter()
        .map(|(name, (frames, accs))| {
            let rows = rows.iter().zip(&accs);
            let rows = rows.map(|((key, _), acc)| acc.finish(key, frames, any_floor));
            (name, rows.collect())
        })
        .collect()
}

/// One loaded frame to score, with its floor box, its sensor's noise model and the view of
/// the previous frame.
struct FrameScoring<'a> {
    frame: &'a RealFrame,
    loaded: &'a LoadedFrame,
    floor_box: Option<[usize; 4]>,
    sensor: SensorNoise,
    other: Option<&'a OtherView>,
}

impl FrameScoring<'_> {
    /// Scores every configuration of `rows` on the frame, adding each into its accumulator of
    /// both `pools` (every frame, the frame's sequence); returns the frame's rows and maps.
    fn score(
        &self,
        pipeline: &mut Pipeline,
        rows: &[(String, PipelineConfig)],
        pools: [&mut [RowAcc]; 2],
    ) -> Result<(Vec<RealRow>, Vec<RowMaps>), BenchError> {
        let mut maps = Vec::new();
        let mut reports = Vec::new();
        let [all, seq] = pools;
        for (((key, cfg), acc), seq_acc) in rows.iter().zip(all).zip(seq) {
            let (one, map) = score_row(pipeline, self, cfg).map_err(|source| BenchError::Run {
                frame: self.frame.name(),
                row: key.clone(),
                source: Box::new(source),
            })?;
            reports.push(one.finish(key, 1, self.floor_box.is_some()));
            acc.merge(&one);
            seq_acc.merge(&one);
            maps.push(map);
        }
        Ok((reports, maps))
    }
}

/// The spec's own figures on a frame.
pub(super) fn spec_summary(loaded: &LoadedFrame, floor_box: Option<[usize; 4]>) -> SpecSummary {
    let r = &loaded.spec.roughness_m;
    SpecSummary {
        floor: floor_box.map(|b| {
            let (v, m) = box_values(r, b);
            floor_stats(v, m)
        }),
        valid_px: r.as_slice().iter().filter(|v| v.is_finite()).count(),
        boundary_px: loaded
            .spec
            .boundary
            .as_slice()
            .iter()
            .filter(|&&b| b)
            .count(),
        hazard_px: r.as_slice().iter().filter(|&&v| v >= HAZARD_M).count(),
        ms: loaded.spec_ms,
    }
}

/// Runs one configuration on a loaded frame and scores it; returns its roughness map too.
fn score_row(
    pipeline: &mut Pipeline,
    scoring: &FrameScoring<'_>,
    cfg: &PipelineConfig,
) -> Result<(RowAcc, RowMaps), RunError> {
    let (loaded, floor_box) = (scoring.loaded, scoring.floor_box);
    let out = pipeline.run(&loaded.input, cfg)?;
    let sensor_depth = loaded
        .input
        .depth_m
        .as_ref()
        .ok_or(RunError::NoSensorDepth)?;
    let mut acc = RowAcc::default();
    let spec = &loaded.spec;
    acc.scores.add(
        &out.roughness_m,
        &spec.roughness_m,
        &spec.boundary,
        sensor_depth,
    )?;
    if let Some(b) = floor_box {
        let (v, m) = box_values(&out.roughness_m, b);
        acc.floor = v;
        acc.floor_missing = m;
    }
    if cfg.mode == Mode::Rgb {
        if let Some(depth) = out.depth_m() {
            acc.depth.add(&depth, sensor_depth)?;
            acc.has_depth = true;
        }
    }
    for (name, took) in out.timings.iter() {
        *acc.ms.entry(name.to_owned()).or_default() += took.as_secs_f64() * 1e3;
    }
    acc.ms
        .insert("total".to_owned(), out.timings.total().as_secs_f64() * 1e3);
    let traversal = three_state(pipeline, scoring, cfg, &out, &mut acc)?;
    let maps = RowMaps {
        roughness_m: out.roughness_m.clone(),
        traversal,
    };
    pipeline.recycle(out);
    Ok((acc, maps))
}

/// The three-state map of a row, when it has one: the mode's calibrated intervals (the spec
/// row of `geometric`, and the learned modes), else the sensor model alone (`geometric`
/// surface-only); adds its shares and safety figures to `acc`.
fn three_state(
    pipeline: &Pipeline,
    scoring: &FrameScoring<'_>,
    cfg: &PipelineConfig,
    out: &tre_pipeline::FrameOutput,
    acc: &mut RowAcc,
) -> Result<Option<Grid<Traversal>>, RunError> {
    let loaded = scoring.loaded;
    let spec_row = cfg.mode != Mode::Geometric || cfg.is_spec();
    let table = pipeline.interval_table_for(cfg).filter(|_| spec_row);
    if cfg.mode == Mode::Rgb && table.is_none() {
        return Ok(None);
    }
    let maps = out.sensor_maps(&loaded.input, cfg.mode, Some(&scoring.sensor), None, table)?;
    let depth = loaded
        .input
        .depth_m
        .as_ref()
        .ok_or(RunError::NoSensorDepth)?;
    let mut t = TraversalAcc::default();
    t.add(&maps, loaded, scoring.floor_box);
    acc.traversal = Some(t);
    let mut safety = SafetyAcc::default();
    safety.add_states(&maps.traversal, &loaded.spec.roughness_m, depth);
    if let Some((lo, hi)) = &maps.interval_m {
        if cfg.mode == Mode::Geometric {
            if let Some(other) = scoring.other {
                let targets = other
                    .pair
                    .shared
                    .iter()
                    .map(|&(i, j)| (i, other.spec_m.as_slice()[j]));
                safety.add_coverage((lo, hi), targets, depth, "another view");
            }
        } else {
            let targets = loaded
                .spec
                .roughness_m
                .as_slice()
                .iter()
                .copied()
                .enumerate();
            safety.add_coverage((lo, hi), targets, depth, "same depth");
        }
    }
    acc.safety = Some(safety);
    Ok(Some(maps.traversal))
}

/// One configuration's maps on a frame, for the contact sheet.
pub struct RowMaps {
    /// Roughness, metres (NaN: none).
    pub roughness_m: Grid<f64>,
    /// The three-state map, for modes that read sensor depth.
    pub traversal: Option<Grid<Traversal>>,
}
