//! `solidsynth._solidsynth`: the Python package's native module, a thin layer over the
//! library's facade (`solidsynth::Solid` and its builder). Every engine decision (defaults,
//! input assembly, analysis cache, memory checks) is the facade's; this layer turns Python
//! arguments into the facade's types, names bad values as the command line names its flags,
//! and runs long calls off the interpreter (`detached`). The same settings give the same bytes
//! as the `solidsynth` command line.

mod detached;
mod errors;
mod evaluate;
mod inputs;
mod ints;
mod settings;
mod turns;

use detached::run_detached;
use errors::{engine_err, invalid, Error};
use inputs::{
    checked_box, exemplar_pair, feature_masks, input_frame, CacheArg, PassesArg, Picture,
};
use ints::Int;
use numpy::prelude::*;
use numpy::{PyArray1, PyArray3, PyArray4};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use settings::SynthSettings;
use solidsynth::analysis::Analysis;
use solidsynth::io::{atomic, ssa};
use solidsynth::solid::{limits, memory, AnalysisCache, ExemplarInput};
use solidsynth::synth::check_tileable_size;
use solidsynth::{
    CancelToken, Compute, CutSpec, Image, Solid, SolidBuilder, SynthOptions, SynthParams, Volume,
};
use std::path::PathBuf;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use turns::Turns;

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A request that panicked is reported as an error and its solid rebuilt (`Engine::ready`):
    // the lock itself stays usable.
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The facade's solid and what rebuilding it takes. A solid's cancellation token is fixed when
/// it is built, so once a request has been cancelled the solid is rebuilt with a fresh token
/// before the next one (the analysis is kept; the synthesizer is made again).
struct Engine {
    solid: Solid,
    token: CancelToken,
    compute: Compute,
    params: SynthParams,
    options: SynthOptions,
    /// A request panicked: the synthesizer's state is not to be trusted.
    broken: bool,
}

impl Engine {
    /// Make the solid usable: rebuilt after a cancellation or a panic.
    fn ready(
        &mut self,
        analysis: &Analysis,
        published: &Mutex<CancelToken>,
    ) -> solidsynth::Result<()> {
        if !(self.broken || self.token.is_cancelled()) {
            return Ok(());
        }
        let token = CancelToken::new();
        let options = SynthOptions {
            cancel: Some(token.clone()),
            ..self.options.clone()
        };
        self.solid = Solid::new(
            analysis,
            self.params.clone(),
            options,
            self.compute.clone(),
            None,
        )?;
        *lock(published) = token.clone();
        self.token = token;
        self.broken = false;
        Ok(())
    }
}

/// A solid texture: a deterministic function over all of Z^3, of which any box, tileable
/// volume or planar cut is synthesized on demand (the same voxels whichever part asked).
///
/// `exemplar` is an image path, a NumPy uint8 array (H, W) or (H, W, C) with C in 1, 3, 4, an
/// `.ssa` analysis file, or None for the built-in exemplar. The other arguments are the
/// command line's flags of the same names, with its defaults.
#[pyclass(name = "Solid", module = "solidsynth", frozen)]
pub struct PySolid {
    engine: Mutex<Engine>,
    /// Whose turn it is to hold `engine`.
    turns: Turns,
    /// The engine's current token, for the calling thread to cancel while its request holds
    /// `engine`.
    token: Mutex<CancelToken>,
    analysis: Arc<Analysis>,
    settings: SynthSettings,
    channels: u32,
    backend: String,
}

impl PySolid {
    /// Analyse (or load, or take from the cache), open the backend and build the solid, off the
    /// interpreter.
    fn open(
        py: Python<'_>,
        builder: SolidBuilder,
        analysis_file: Option<PathBuf>,
        settings: SynthSettings,
    ) -> PyResult<PySolid> {
        let options = settings.synth_options();
        options.validate().map_err(engine_err)?;
        let token = CancelToken::new();
        let first = SynthOptions {
            cancel: Some(token.clone()),
            ..options.clone()
        };
        let params = settings.params.clone();
        // The engine's warnings (an analysis cache it cannot write), raised as Python warnings
        // once the work is done, on this thread.
        let warnings = Arc::new(Mutex::new(Vec::<String>::new()));
        let sink = warnings.clone();
        let builder = builder.warnings(move |text| lock(&sink).push(text.to_string()));
        let built = run_detached(
            py,
            || token.cancel(),
            move || {
                let builder = match analysis_file {
                    Some(path) => builder.analysis(ssa::load(&path)?),
                    None => builder,
                };
                let compute = builder.open_compute()?;
                let analysis = builder.analyze_on(&compute)?;
                let solid = Solid::new(&analysis, params, first, compute.clone(), None)?;
                Ok((compute, analysis, solid))
            },
        );
        for text in lock(&warnings).drain(..) {
            let message = std::ffi::CString::new(text).unwrap_or_default();
            PyErr::warn(
                py,
                &py.get_type::<pyo3::exceptions::PyUserWarning>(),
                &message,
                1,
            )?;
        }
        let (compute, analysis, solid) = built?;
        Ok(PySolid {
            channels: solid.color_channels(),
            backend: compute.describe(),
            turns: Turns::default(),
            engine: Mutex::new(Engine {
                solid,
                token: token.clone(),
                compute,
                params: settings.params.clone(),
                options,
                broken: false,
            }),
            token: Mutex::new(token),
            analysis,
            settings,
        })
    }

    /// Run `work` on the solid off the interpreter; Ctrl-C cancels it. Requests from several
    /// Python threads take turns; Ctrl-C cancels the caller's own request only (at once, also
    /// while it waits), not one of another thread that it is waiting behind.
    fn request<T: Send>(
        &self,
        py: Python<'_>,
        work: impl FnOnce(&mut Solid) -> solidsynth::Result<T> + Send,
    ) -> PyResult<T> {
        // The request's phase, changed under one lock with the interrupt's look at it: the
        // token is cancelled only while this request runs, never before (the request is then
        // refused when it starts) nor after it ends (the worker marks it done while it still
        // holds the engine, so no other thread's request can be running on the token then).
        let phase = Mutex::new(Phase::Waiting);
        run_detached(
            py,
            || {
                let mut phase = lock(&phase);
                if *phase == Phase::Running {
                    lock(&self.token).cancel();
                }
                if *phase == Phase::Waiting {
                    *phase = Phase::Abandoned;
                }
            },
            || {
                // Taken on the worker thread: a request waiting for another one waits there,
                // with the interpreter free, and gives up as soon as its caller is interrupted
                // (a blocking lock would hold the KeyboardInterrupt until the other request
                // ended, minutes for a large box).
                let Some(_turn) = self.turns.take(|| *lock(&phase) == Phase::Abandoned) else {
                    return Err(solidsynth::Error::Cancelled);
                };
                let mut engine = lock(&self.engine);
                engine.ready(&self.analysis, &self.token)?;
                {
                    let mut phase = lock(&phase);
                    if *phase == Phase::Abandoned {
                        return Err(solidsynth::Error::Cancelled);
                    }
                    *phase = Phase::Running;
                }
                let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    work(&mut engine.solid)
                }));
                *lock(&phase) = Phase::Done;
                match outcome {
                    Ok(result) => result,
                    Err(panic) => {
                        engine.broken = true;
                        std::panic::resume_unwind(panic)
                    }
                }
            },
        )
    }
}

/// Where a request stands, for Ctrl-C (`PySolid::request`).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Phase {
    Waiting,
    Abandoned,
    Running,
    Done,
}

/// A volume as a (Z, Y, X, C) array: its bytes are already in that order (x fastest, channels
/// interleaved), so the vector becomes the array's buffer and is reshaped without a copy.
fn volume_array(py: Python<'_>, v: Volume) -> PyResult<Bound<'_, PyArray4<u8>>> {
    let shape = [
        v.nz as usize,
        v.ny as usize,
        v.nx as usize,
        v.channels as usize,
    ];
    PyArray1::from_vec(py, v.data).reshape(shape)
}

/// An image as a (H, W, C) array, without a copy.
fn image_array(py: Python<'_>, image: Image) -> PyResult<Bound<'_, PyArray3<u8>>> {
    let shape = [
        image.height as usize,
        image.width as usize,
        image.channels as usize,
    ];
    PyArray1::from_vec(py, image.pixels).reshape(shape)
}

#[pymethods]
impl PySolid {
    #[new]
    #[pyo3(signature = (
        exemplar=None, *, ey=None, ez=None, seed=Int::of(0), jitter=1.0,
        backend=String::from("auto"), adapter=None, candidates=String::from("3d"),
        passes=PassesArg::count(2), color=String::from("average"), coarse_cache=None,
        max_group=None, frame=None, feature_mask=None, ey_feature_mask=None,
        ez_feature_mask=None, feature_weight=None, periodic=false, balance_rounds=None,
        balance_strength=1.0, cache=CacheArg::Flag(true)
    ), text_signature = "(exemplar=None, *, ey=None, ez=None, seed=0, jitter=1.0, \
        backend='auto', adapter=None, candidates='3d', passes=2, color='average', \
        coarse_cache=None, max_group=None, frame=None, feature_mask=None, \
        ey_feature_mask=None, ez_feature_mask=None, feature_weight=None, periodic=False, \
        balance_rounds=None, balance_strength=1.0, cache=True)")]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        exemplar: Option<&Bound<'_, PyAny>>,
        ey: Option<&Bound<'_, PyAny>>,
        ez: Option<&Bound<'_, PyAny>>,
        seed: Int,
        jitter: f32,
        backend: String,
        adapter: Option<String>,
        candidates: String,
        passes: PassesArg,
        color: String,
        coarse_cache: Option<Int>,
        max_group: Option<Int>,
        frame: Option<String>,
        feature_mask: Option<&Bound<'_, PyAny>>,
        ey_feature_mask: Option<&Bound<'_, PyAny>>,
        ez_feature_mask: Option<&Bound<'_, PyAny>>,
        feature_weight: Option<f32>,
        periodic: bool,
        balance_rounds: Option<Int>,
        balance_strength: f32,
        cache: CacheArg,
    ) -> PyResult<PySolid> {
        let settings = SynthSettings::parse(
            seed,
            jitter,
            backend,
            adapter,
            &candidates,
            &passes,
            &color,
            coarse_cache,
            max_group,
        )?;
        let main = exemplar
            .map(|e| Picture::from_arg(e, "exemplar"))
            .transpose()?;
        let pair = exemplar_pair(ey, ez)?;
        if main.is_none() && pair.is_some() {
            return Err(invalid("--ey", "needs the x exemplar INPUT too"));
        }
        // An `.ssa` INPUT is the analysis; any exemplar-side setting given with it is refused
        // by the facade (`SolidBuilder::analyze_on`), as by the command line.
        let analysis_file = main
            .as_ref()
            .and_then(Picture::analysis_path)
            .map(|p| p.to_path_buf());
        let main = main.filter(|_| analysis_file.is_none());
        let mut images = Vec::new();
        let mut names = Vec::new();
        let (y, z) = pair.map_or((None, None), |(y, z)| (Some(y), Some(z)));
        for (picture, what) in [(main, "exemplar"), (y, "--ey"), (z, "--ez")] {
            if let Some(picture) = picture {
                let (image, name) = picture.load(py, what)?;
                images.push(image);
                names.push(name);
            }
        }
        let masks = [feature_mask, ey_feature_mask, ez_feature_mask];
        let defaults = ExemplarInput::default();
        let input = ExemplarInput {
            feature_masks: feature_masks(py, masks, images.len())?,
            images,
            names,
            frame: input_frame(frame.as_deref())?,
            feature_weight: feature_weight.unwrap_or(defaults.feature_weight),
            periodic,
            balance_rounds: match balance_rounds {
                Some(rounds) => rounds.in_range("balance_rounds")?,
                None => defaults.balance_rounds,
            },
            balance_strength,
        };
        let cache = match cache {
            CacheArg::Flag(true) => AnalysisCache::user_default(),
            CacheArg::Flag(false) => None,
            CacheArg::Dir(dir) => Some(AnalysisCache::at(dir)),
        };
        let builder = Solid::builder()
            .backend(settings.choice, settings.gpu_options())
            .exemplar_input(input)
            .cache(cache);
        PySolid::open(py, builder, analysis_file, settings)
    }

    /// The solid of an analysis file (`.ssa`, written by `save_analysis` or `solidsynth
    /// analyze`) with these synthesis settings.
    #[staticmethod]
    #[pyo3(signature = (
        path, *, seed=Int::of(0), jitter=1.0, backend=String::from("auto"), adapter=None,
        candidates=String::from("3d"), passes=PassesArg::count(2),
        color=String::from("average"), coarse_cache=None, max_group=None
    ), text_signature = "(path, *, seed=0, jitter=1.0, backend='auto', adapter=None, \
        candidates='3d', passes=2, color='average', coarse_cache=None, max_group=None)")]
    #[allow(clippy::too_many_arguments)]
    fn load(
        py: Python<'_>,
        path: PathBuf,
        seed: Int,
        jitter: f32,
        backend: String,
        adapter: Option<String>,
        candidates: String,
        passes: PassesArg,
        color: String,
        coarse_cache: Option<Int>,
        max_group: Option<Int>,
    ) -> PyResult<PySolid> {
        let settings = SynthSettings::parse(
            seed,
            jitter,
            backend,
            adapter,
            &candidates,
            &passes,
            &color,
            coarse_cache,
            max_group,
        )?;
        let builder = Solid::builder().backend(settings.choice, settings.gpu_options());
        PySolid::open(py, builder, Some(path), settings)
    }

    /// The voxels of the half-open box [lo, hi) of the infinite solid, any coordinates (x, y,
    /// z), as a uint8 array of shape (Z, Y, X, C).
    fn region<'py>(
        &self,
        py: Python<'py>,
        lo: [Int; 3],
        hi: [Int; 3],
    ) -> PyResult<Bound<'py, PyArray4<u8>>> {
        let b = checked_box(lo, hi)?;
        let volume = self.request(py, move |solid| solid.region(b))?;
        volume_array(py, volume)
    }

    /// The n^3 tileable solid (n a multiple of 32): its own solid, periodic with period n
    /// along each axis, as (n, n, n, C).
    fn tileable<'py>(&self, py: Python<'py>, n: Int) -> PyResult<Bound<'py, PyArray4<u8>>> {
        // As `synth --size N --tileable` checks it.
        let n: i64 = n.or_refused(limits::check_size("--size", 0).unwrap_err())?;
        let n = limits::check_size(&format!("--size {n}"), n).map_err(engine_err)?;
        check_tileable_size(n).map_err(engine_err)?;
        if self.settings.params.coarse_cache.is_some() {
            return Err(invalid(
                "--coarse-cache with --tileable",
                "the cache builds regions of the infinite solid; a tileable solid is its own \
                 periodic definition: give one or the other",
            ));
        }
        let volume = self.request(py, move |solid| solid.tileable(n))?;
        volume_array(py, volume)
    }

    /// A planar cut at any angle: `size` x `size` pixels `spacing` voxels apart, centred on
    /// `origin`, across `normal`, as (size, size, C). Pixel [j, i] samples origin +
    /// (i + 0.5 - size/2) * spacing * u + (j + 0.5 - size/2) * spacing * v, where v is `up`
    /// projected onto the plane (default +y; +z for a normal along y) and u = v x normal: for
    /// normal (0, 0, 1) the array is [y, x], like a z slice of `region`; shown as an image
    /// (row 0 at the top), `up` points down.
    #[pyo3(signature = (origin, normal, up=None, size=Int::of(256), spacing=1.0),
           text_signature = "($self, origin, normal, up=None, size=256, spacing=1.0)")]
    fn cut<'py>(
        &self,
        py: Python<'py>,
        origin: [f64; 3],
        normal: [f64; 3],
        up: Option<[f64; 3]>,
        size: Int,
        spacing: f64,
    ) -> PyResult<Bound<'py, PyArray3<u8>>> {
        let size: i64 = size.or_refused(limits::check_cut_size("--size", 0).unwrap_err())?;
        let size = limits::check_cut_size(&format!("--size {size}"), size).map_err(engine_err)?;
        let spec = CutSpec {
            origin,
            normal,
            up,
            size,
            spacing,
        };
        spec.frame().map_err(engine_err)?;
        // `Solid::cut`'s own check, made before waiting for a turn; the array takes the
        // image's bytes without a copy.
        memory::check_cut_request(
            &spec,
            self.settings.max_group,
            self.settings.params.coarse_cache,
            0,
        )
        .map_err(engine_err)?;
        let image = self.request(py, move |solid| solid.cut(&spec))?;
        image_array(py, image)
    }

    /// Write the analysis as an `.ssa` file (what `solidsynth analyze` writes), atomically.
    fn save_analysis(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        if path.as_os_str().is_empty() {
            return Err(invalid("-o ''", "is an empty path"));
        }
        atomic::check_output_path(&path, "-o").map_err(engine_err)?;
        let analysis = self.analysis.clone();
        run_detached(py, || {}, move || ssa::save(&analysis, &path))
    }

    /// Colour channels of the arrays returned (the exemplars').
    #[getter]
    fn channels(&self) -> u32 {
        self.channels
    }

    /// The backend the kernels run on, described (`cpu (16 threads)`, `gpu NAME ...`).
    #[getter]
    fn backend(&self) -> String {
        self.backend.clone()
    }

    /// The synthesis settings, as `Solid.load` takes them: `Solid.load(path, **solid.options)`
    /// with this solid's analysis is this solid.
    #[getter]
    fn options<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = &self.settings;
        let d = PyDict::new(py);
        d.set_item("seed", s.params.seed)?;
        d.set_item("jitter", s.params.jitter)?;
        d.set_item("backend", s.backend.clone())?;
        d.set_item("adapter", s.adapter.clone())?;
        d.set_item("candidates", s.params.candidates.to_string())?;
        d.set_item("passes", s.params.passes.to_string())?;
        d.set_item("color", s.params.color.to_string())?;
        d.set_item("coarse_cache", s.params.coarse_cache)?;
        d.set_item("max_group", s.max_group)?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!(
            "Solid(seed={}, channels={}, backend={:?})",
            self.settings.params.seed, self.channels, self.backend
        )
    }
}

#[pymodule]
fn _solidsynth(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySolid>()?;
    m.add_function(wrap_pyfunction!(evaluate::evaluate, m)?)?;
    m.add("Error", m.py().get_type::<Error>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    // The request limits, for the Python side's own checks (solidsynth.dask).
    m.add("MAX_BOX_SIDE", limits::MAX_BOX_SIDE)?;
    m.add("COORDINATE_LIMIT", limits::COORDINATE_LIMIT)?;
    Ok(())
}
