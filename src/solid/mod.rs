//! The library's front door: a [`Solid`], built by a [`SolidBuilder`] that owns everything that
//! makes a solid (the exemplars and how they are analysed, the analysis cache, the synthesis
//! parameters, the backend) with the command line's defaults, so the same settings give the same
//! bytes through the library, the `solidsynth` tool and its server. Then any part of the
//! infinite solid: boxes (returned, into a caller's buffer, or streamed in slabs), tileable
//! volumes, planar cuts (one-off or warm), surface bakes; memory estimates before running;
//! progress through a callback and cancellation through a token.
//!
//! ```
//! use solidsynth::{Box3, Solid};
//! // The built-in exemplar, analysed (a few seconds), then a box of its solid on the CPU.
//! let mut solid = Solid::builder().seed(7).cpu().build()?;
//! let volume = solid.region(Box3::new([-8, 0, 0], [8, 16, 4]))?;
//! assert_eq!((volume.nx, volume.ny, volume.nz), (16, 16, 4));
//! // Any box holds the same voxels as any larger box around it.
//! let inner = solid.region(Box3::new([-4, 2, 1], [4, 10, 3]))?;
//! assert_eq!(inner.at(0, 0, 0), volume.at(4, 2, 1));
//! # Ok::<(), solidsynth::Error>(())
//! ```

pub mod cache;
pub mod input;
pub mod limits;
pub mod memory;
pub mod surface;

use crate::analysis::frame::InputFrame;
use crate::analysis::Analysis;
use crate::backend::{BackendChoice, Compute};
use crate::error::{Error, Result};
use crate::exemplar::Image;
use crate::gpu::GpuOptions;
use crate::lazy;
use crate::lazy::cut::{CutSession, CutSpec};
use crate::lazy::{
    Box3, CandidateMode, ColorSource, PassSchedule, Slab, SynthOptions, SynthParams, SynthStats,
    Synthesizer,
};
use crate::util::cancel::CancelToken;
use crate::volume::Volume;
pub use cache::AnalysisCache;
pub use input::{ExemplarInput, FeatureMasks};
use std::sync::Arc;

/// Progress reports: (stage, fraction of the whole job).
pub type ProgressFn = Arc<dyn Fn(&str, f32) + Send + Sync>;

/// A callback for warnings (work goes on: an analysis cache that cannot be written).
pub type WarningFn = Arc<dyn Fn(&str) + Send + Sync>;

/// Where the kernels run.
#[derive(Clone)]
enum Backend {
    Choice(BackendChoice, GpuOptions),
    Open(Compute),
}

/// Builds a [`Solid`]. Every setting has the command line's default; the flag each one mirrors
/// is named in its documentation, and bad values are refused with that flag's name.
#[derive(Clone)]
pub struct SolidBuilder {
    input: ExemplarInput,
    analysis: Option<Arc<Analysis>>,
    params: SynthParams,
    options: SynthOptions,
    backend: Backend,
    cache: Option<AnalysisCache>,
    progress: Option<ProgressFn>,
    warnings: Option<WarningFn>,
}

impl Default for SolidBuilder {
    fn default() -> Self {
        SolidBuilder {
            input: ExemplarInput::default(),
            analysis: None,
            params: SynthParams::default(),
            options: SynthOptions::default(),
            backend: Backend::Choice(BackendChoice::Auto, GpuOptions::from_env()),
            cache: None,
            progress: None,
            warnings: None,
        }
    }
}

impl SolidBuilder {
    /// One exemplar image for all three planes (INPUT).
    pub fn exemplar(mut self, image: Image) -> Self {
        self.input.images = vec![image];
        self.input.names = Vec::new();
        self
    }

    /// The exemplars of the planes orthogonal to x, y and z (INPUT, `--ey`, `--ez`).
    pub fn exemplars(mut self, x: Image, y: Image, z: Image) -> Self {
        self.input.images = vec![x, y, z];
        self.input.names = Vec::new();
        self
    }

    /// Names of the exemplars for messages (e.g. their paths), in the order given.
    pub fn exemplar_names(mut self, names: Vec<String>) -> Self {
        self.input.names = names;
        self
    }

    /// All exemplar-side settings at once.
    pub fn exemplar_input(mut self, input: ExemplarInput) -> Self {
        self.input = input;
        self
    }

    /// How the exemplars lie in the three planes (`--frame`).
    pub fn frame(mut self, frame: InputFrame) -> Self {
        self.input.frame = Some(frame);
        self
    }

    /// The feature channel's masks (`--feature-mask`).
    pub fn feature_masks(mut self, masks: FeatureMasks) -> Self {
        self.input.feature_masks = masks;
        self
    }

    /// Weight of the feature channel (`--feature-weight`).
    pub fn feature_weight(mut self, weight: f32) -> Self {
        self.input.feature_weight = weight;
        self
    }

    /// The exemplars tile (`--periodic`).
    pub fn periodic(mut self, periodic: bool) -> Self {
        self.input.periodic = periodic;
        self
    }

    /// Usage-balancing rounds and strength (`--balance-rounds`, `--balance-strength`).
    pub fn balance(mut self, rounds: u32, strength: f32) -> Self {
        self.input.balance_rounds = rounds;
        self.input.balance_strength = strength;
        self
    }

    /// A finished analysis (an `.ssa` file's, [`crate::io::ssa::load`]) instead of analysing
    /// exemplars.
    pub fn analysis(mut self, analysis: Analysis) -> Self {
        self.analysis = Some(Arc::new(analysis));
        self
    }

    /// [`Self::analysis`], shared with other solids.
    pub fn shared_analysis(mut self, analysis: Arc<Analysis>) -> Self {
        self.analysis = Some(analysis);
        self
    }

    /// Keep analyses in `cache` (None: analyse every time, the library's default; the
    /// command line uses [`AnalysisCache::user_default`]).
    pub fn cache(mut self, cache: Option<AnalysisCache>) -> Self {
        self.cache = cache;
        self
    }

    /// The solid's seed (`--seed`).
    pub fn seed(mut self, seed: u64) -> Self {
        self.params.seed = seed;
        self
    }

    /// Jitter strength (`--jitter`).
    pub fn jitter(mut self, jitter: f32) -> Self {
        self.params.jitter = jitter;
        self
    }

    /// Candidate mode (`--candidates`).
    pub fn candidates(mut self, mode: CandidateMode) -> Self {
        self.params.candidates = mode;
        self
    }

    /// Correction passes per level (`--passes`).
    pub fn passes(mut self, passes: PassSchedule) -> Self {
        self.params.passes = passes;
        self
    }

    /// How voxel colours are made (`--color`).
    pub fn color(mut self, color: ColorSource) -> Self {
        self.params.color = color;
        self
    }

    /// The coarse-level cache's period (`--coarse-cache`).
    pub fn coarse_cache(mut self, period: Option<u32>) -> Self {
        self.params.coarse_cache = period;
        self
    }

    /// All synthesis parameters at once.
    pub fn params(mut self, params: SynthParams) -> Self {
        self.params = params;
        self
    }

    /// The largest group edge (`--max-group`).
    pub fn max_group(mut self, side: Option<u32>) -> Self {
        self.options.max_group = side;
        self
    }

    /// How the synthesizer runs (groups, warm buffers, profiling): never what it computes.
    pub fn options(mut self, options: SynthOptions) -> Self {
        self.options = options;
        self
    }

    /// Where kernels run (`--backend`), with these GPU options (`--adapter`, timeouts).
    pub fn backend(mut self, choice: BackendChoice, gpu: GpuOptions) -> Self {
        self.backend = Backend::Choice(choice, gpu);
        self
    }

    /// The CPU backend (`--backend cpu`).
    pub fn cpu(self) -> Self {
        self.backend(BackendChoice::Cpu, GpuOptions::default())
    }

    /// An opened backend: for example an application's own wgpu device
    /// ([`crate::gpu::GpuContext::from_device`] in a [`Compute::Gpu`]).
    pub fn compute(mut self, compute: Compute) -> Self {
        self.backend = Backend::Open(compute);
        self
    }

    /// Progress reports of the analysis and of every box, tileable solid, surface and sample
    /// request: (stage, fraction). Cuts, which take milliseconds to a second, report none.
    pub fn progress(mut self, report: impl Fn(&str, f32) + Send + Sync + 'static) -> Self {
        self.progress = Some(Arc::new(report));
        self
    }

    /// Warnings about work that goes on regardless (an analysis cache that cannot be written or
    /// holds a damaged file), also logged through `tracing`: for an application whose users
    /// see no log.
    pub fn warnings(mut self, warn: impl Fn(&str) + Send + Sync + 'static) -> Self {
        self.warnings = Some(Arc::new(warn));
        self
    }

    /// Stop work at its next check (between groups and correction passes) once `token` is
    /// cancelled, with [`Error::Cancelled`]. A token stays cancelled: every later request
    /// stops too, until [`Solid::set_cancel`] gives the solid a new one.
    pub fn cancel(mut self, token: CancelToken) -> Self {
        self.options.cancel = Some(token);
        self
    }

    /// The exemplar-side settings (e.g. to name them in messages).
    pub fn input(&self) -> &ExemplarInput {
        &self.input
    }

    /// The synthesis parameters.
    pub fn synth_params(&self) -> &SynthParams {
        &self.params
    }

    /// Open the backend.
    pub fn open_compute(&self) -> Result<Compute> {
        match &self.backend {
            Backend::Open(c) => Ok(c.clone()),
            Backend::Choice(choice, gpu) => Compute::open(*choice, gpu),
        }
    }

    /// The analysis this solid reads, on `compute`: the one given, or the cached one, or the
    /// exemplars analysed (and cached).
    pub fn analyze_on(&self, compute: &Compute) -> Result<Arc<Analysis>> {
        if let Some(a) = &self.analysis {
            if self.input.analysis_settings_given() || !self.input.images.is_empty() {
                return Err(Error::invalid(
                    "--ey/--frame/--periodic/--feature-mask/--feature-weight/--balance-rounds/\
                     --balance-strength",
                    "are analysis inputs; an .ssa file already holds them",
                ));
            }
            return Ok(a.clone());
        }
        let (input, params) = self.input.analysis_input()?;
        let report = |stage: &str, f: f32| {
            if let Some(p) = &self.progress {
                p(&format!("analysis {stage}"), f)
            }
        };
        let analyze = || crate::lazy::analyze(&input, &params, compute, &report);
        let warn = |text: &str| {
            if let Some(w) = &self.warnings {
                w(text)
            }
        };
        let analysis = match &self.cache {
            Some(cache) => {
                cache.get_or_analyze_warning(cache::cache_key(&input, &params), analyze, &warn)?
            }
            None => analyze()?,
        };
        Ok(Arc::new(analysis))
    }

    /// The analysis alone (what `solidsynth analyze` writes), on this builder's backend.
    pub fn analyze(&self) -> Result<Arc<Analysis>> {
        let compute = self.open_compute()?;
        self.analyze_on(&compute)
    }

    /// The solid: the backend opened, the analysis made (or loaded), the synthesizer ready.
    pub fn build(self) -> Result<Solid> {
        self.params.validate()?;
        self.options.validate()?;
        let compute = self.open_compute()?;
        let analysis = self.analyze_on(&compute)?;
        Solid::new(&analysis, self.params, self.options, compute, self.progress)
    }
}

/// A solid texture ready to synthesize any part of: see the module documentation.
pub struct Solid {
    synth: Synthesizer,
    compute: Compute,
    progress: Option<ProgressFn>,
}

impl std::fmt::Debug for Solid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Solid")
            .field("params", &self.synth.params)
            .field("backend", &self.compute.describe())
            .field("color_channels", &self.color_channels())
            .finish()
    }
}

impl std::fmt::Debug for SolidBuilder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SolidBuilder")
            .field("params", &self.params)
            .field("given_analysis", &self.analysis.is_some())
            .field("caches", &self.cache.is_some())
            .finish_non_exhaustive()
    }
}

fn silent(_: &str, _: f32) {}

/// The progress callback as the synthesizer takes it.
fn reporter(progress: &Option<ProgressFn>) -> &(dyn Fn(&str, f32) + Sync) {
    match progress {
        Some(p) => &**p,
        None => &silent,
    }
}

impl Solid {
    /// A builder with the command line's defaults (the built-in exemplar, seed 0, the default
    /// backend).
    pub fn builder() -> SolidBuilder {
        SolidBuilder::default()
    }

    /// The solid of `analysis` with these parameters and options on `compute`.
    pub fn new(
        analysis: &Analysis,
        params: SynthParams,
        options: SynthOptions,
        compute: Compute,
        progress: Option<ProgressFn>,
    ) -> Result<Solid> {
        let synth = Synthesizer::with_options(analysis, params, &compute, options)?;
        Ok(Solid {
            synth,
            compute,
            progress,
        })
    }

    /// Colour channels of the volumes and images produced.
    pub fn color_channels(&self) -> u32 {
        self.synth.color_channels()
    }

    /// The backend the kernels run on.
    pub fn compute(&self) -> &Compute {
        &self.compute
    }

    /// Voxels synthesized per level and peak state memory of the last request.
    pub fn last_stats(&self) -> Option<&SynthStats> {
        self.synth.last_stats()
    }

    /// The engine underneath (for requests the facade does not name).
    pub fn synthesizer(&mut self) -> &mut Synthesizer {
        &mut self.synth
    }

    /// The bytes a box of `size` voxels needs: the engine's working set in this solid's groups
    /// and the returned volume, before anything is allocated.
    pub fn box_memory_estimate(&self, size: [u64; 3]) -> u64 {
        let largest = size.into_iter().max().unwrap_or(0).min(u32::MAX as u64) as u32;
        lazy::memory::box_working_bytes(
            size,
            self.box_group().min(largest),
            self.synth.params.coarse_cache,
        ) + self.volume_bytes(size)
    }

    /// Refuse a box whose estimate ([`Solid::box_memory_estimate`]) exceeds the memory
    /// available, naming `what` (the request as the command line names it).
    pub fn check_box_memory(&self, what: &str, size: [u64; 3]) -> Result<u64> {
        memory::check_box(
            what,
            size,
            self.box_group(),
            self.synth.params.coarse_cache,
            self.volume_bytes(size),
        )
    }

    /// The group edge the synthesizer gives boxes.
    fn box_group(&self) -> u32 {
        self.synth
            .volume_group_limit()
            .unwrap_or(lazy::memory::LARGEST_GROUP)
    }

    fn volume_bytes(&self, size: [u64; 3]) -> u64 {
        size.iter().fold(self.color_channels() as u64, |bytes, &d| {
            bytes.saturating_mul(d)
        })
    }

    /// Refuse an empty box, or one beyond the coordinates the engine addresses (+-2^28).
    fn check_box(b: Box3) -> Result<()> {
        if b.is_empty() {
            return Err(Error::invalid(
                box_flag(b),
                "each side must be at least one voxel (X1 > X0, Y1 > Y0, Z1 > Z0)",
            ));
        }
        let limit = limits::COORDINATE_LIMIT;
        if b.lo.iter().chain(&b.hi).any(|&c| (c as i64).abs() > limit) {
            return Err(Error::invalid(
                box_flag(b),
                format!("coordinates must lie within +-{limit}"),
            ));
        }
        Ok(())
    }

    /// The voxels of box `b` of the infinite solid (half-open, any coordinates), refused before
    /// allocating when they cannot fit in memory.
    pub fn region(&mut self, b: Box3) -> Result<Volume> {
        Self::check_box(b)?;
        self.check_box_memory(&box_flag(b), b.size().map(u64::from))?;
        let report = reporter(&self.progress);
        self.synth.synthesize(b, report)
    }

    /// [`Self::region`] with the finest level's triples: 3 packed exemplar coordinates per voxel.
    pub fn region_with_triples(&mut self, b: Box3) -> Result<(Volume, Vec<u32>)> {
        Self::check_box(b)?;
        self.check_box_memory(&box_flag(b), b.size().map(u64::from))?;
        let report = reporter(&self.progress);
        self.synth.synthesize_with_triples(b, report)
    }

    /// [`Self::region`] into the caller's buffer: `color_channels` bytes per voxel, x fastest,
    /// then y, then z. The buffer must hold exactly the box.
    pub fn region_into(&mut self, b: Box3, out: &mut [u8]) -> Result<()> {
        Self::check_box(b)?;
        let size = b.size();
        let channels = self.color_channels() as usize;
        let want = size
            .iter()
            .fold(channels as u64, |bytes, &d| bytes.saturating_mul(d as u64));
        if out.len() as u64 != want {
            return Err(Error::invalid(
                "output buffer",
                format!("holds {} bytes; the box needs {want}", out.len()),
            ));
        }
        let slice = size[0] as usize * size[1] as usize * channels;
        self.region_slabs(b, false, |slab| {
            let at = slab.z0 as usize * slice;
            out[at..at + slab.volume.data.len()].copy_from_slice(&slab.volume.data);
            Ok(())
        })
    }

    /// Box `b` handed to `sink` in slabs along z, in order, one held at a time: a large box in
    /// bounded memory (with groups bounded, [`SynthOptions::max_group`]).
    pub fn region_slabs(
        &mut self,
        b: Box3,
        want_triples: bool,
        sink: impl FnMut(Slab) -> Result<()>,
    ) -> Result<()> {
        Self::check_box(b)?;
        let report = reporter(&self.progress);
        self.synth.synthesize_slabs(b, report, want_triples, sink)
    }

    /// The n^3 tileable solid (`synth --tileable`; n a multiple of 32): its own deterministic
    /// solid, periodic with period n along each axis.
    pub fn tileable(&mut self, n: u32) -> Result<Volume> {
        crate::lazy::check_tileable_size(n)?;
        self.check_box_memory(&format!("--size {n}"), [n as u64; 3])?;
        let report = reporter(&self.progress);
        Ok(self.synth.synthesize_tileable(n, report, false)?.0)
    }

    /// A planar cut (any orientation) as an image of the solid's colour channels, refused
    /// before anything is allocated when it cannot fit in the memory available
    /// ([`memory::check_cut`]; a [`CutSession`]'s caller checks its largest cut itself).
    pub fn cut(&mut self, spec: &CutSpec) -> Result<Image> {
        spec.frame()?;
        memory::check_cut_request(
            spec,
            self.synth.options().max_group,
            self.synth.params.coarse_cache,
            0,
        )?;
        crate::lazy::cut::cut(&mut self.synth, spec)
    }

    /// A warm session for repeated cuts (the device keeps its buffers between them).
    pub fn into_cut_session(self) -> CutSession {
        CutSession::new(self.synth)
    }

    /// Replace the cancellation token its requests check (None: they run to the end): after a
    /// cancellation, a new token lets the solid work again.
    pub fn set_cancel(&mut self, token: Option<CancelToken>) {
        self.synth.set_cancel(token);
    }

    /// The packed colours of voxels in any order (a cut's or an atlas' points).
    pub fn sample(&mut self, voxels: &[[i32; 3]]) -> Result<Vec<u32>> {
        let report = reporter(&self.progress);
        self.synth.sample(voxels, report)
    }
}

/// How the command line names a box request.
fn box_flag(b: Box3) -> String {
    format!(
        "--box {},{},{},{},{},{}",
        b.lo[0], b.lo[1], b.lo[2], b.hi[0], b.hi[1], b.hi[2]
    )
}
