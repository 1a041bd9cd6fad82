//! The server's state: solids (a warm cut session each, and a preview volume), background jobs
//! that make them (analysis, then the preview volume) or bake surfaces (`super::surfaces`), and
//! the lock that serializes all synthesis work but surface bakes.

use super::ServeConfig;
use crate::analysis::Analysis;
use crate::backend::Compute;
use crate::error::{Error, Result};
use crate::exemplar::{self, procedural, Image};
use crate::lazy::cut::CutSession;
use crate::lazy::{Box3, SynthOptions, SynthParams, Synthesizer};
use crate::solid::FeatureMasks;
use crate::util::cancel::CancelToken;
use crate::volume::Volume;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Instant;

/// Lock a mutex even if a thread panicked while holding it: every value behind our mutexes is
/// left consistent between statements (a panicking request must not take the server down).
pub fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// A built-in exemplar the page can pick.
pub struct Builtin {
    pub name: &'static str,
    pub description: &'static str,
    make: fn() -> Image,
}

impl Builtin {
    pub fn image(&self) -> Image {
        (self.make)()
    }
}

/// The built-in exemplars: all tileable, made by this crate (no third-party images).
pub const BUILTINS: &[Builtin] = &[
    Builtin {
        name: "cells",
        description: "slice of a procedural 3D cell solid (the default exemplar)",
        make: exemplar::default_exemplar,
    },
    Builtin {
        name: "cobblestone",
        description: "procedural cobblestones: rounded stones, dark mortar",
        make: || procedural::cobblestone(128, 40, 7),
    },
    Builtin {
        name: "marble",
        description: "procedural veined marble",
        make: || procedural::marble(128, 11),
    },
];

pub fn builtin(name: &str) -> Option<&'static Builtin> {
    BUILTINS.iter().find(|b| b.name == name)
}

/// What a new solid is made from.
pub enum Source {
    /// An exemplar image (decoded), analysed by the job; `periodic` chooses the border rule.
    Image {
        name: String,
        image: Image,
        periodic: bool,
    },
    /// An analysis already at hand (an .ssa given on the command line).
    Analysis {
        name: String,
        analysis: Arc<Analysis>,
    },
}

/// How a new solid is synthesized: the page's parameters over the server's.
#[derive(Clone, Debug)]
pub struct SolidSettings {
    /// The seed is the solid's.
    pub params: SynthParams,
    /// The feature channel of an image's analysis.
    pub feature_masks: FeatureMasks,
}

/// A solid ready to cut.
pub struct Solid {
    pub id: u64,
    pub name: String,
    pub seed: u64,
    pub channels: u32,
    /// What it was made from and with (surface bakes make their own synthesizer of it).
    pub analysis: Arc<Analysis>,
    pub params: SynthParams,
    /// The box [0, preview_size)^3, synthesized with the solid.
    pub preview: Arc<Volume>,
    session: Mutex<CutSession>,
    /// The last other-sized volume asked for (downloads), so a repeated download is free.
    extra: Mutex<Option<Arc<Volume>>>,
}

impl Solid {
    pub fn info(&self) -> serde_json::Value {
        let p = &self.params;
        serde_json::json!({"id": self.id, "name": self.name, "seed": self.seed,
            "channels": self.channels, "preview_size": self.preview.nx,
            "params": {"jitter": p.jitter, "color": p.color.to_string(),
                "passes": p.passes.to_string(), "coarse_cache": p.coarse_cache}})
    }
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct JobStatus {
    pub id: u64,
    /// "solid" (analysis and preview) or "surface" (a bake).
    pub kind: &'static str,
    pub name: String,
    /// "queued", "running", "done", "failed" or "cancelled".
    pub state: &'static str,
    pub stage: String,
    /// 0..=1.
    pub progress: f32,
    /// The solid made, or baked.
    pub solid: Option<u64>,
    /// The surface baked (`/api/surfaces/ID.glb`).
    pub surface: Option<u64>,
    pub error: Option<String>,
    pub seconds: f64,
}

pub struct Job {
    status: Mutex<JobStatus>,
    started: Instant,
    /// Cancels the job's synthesis at its next group or pass.
    pub cancel: CancelToken,
}

/// What a finished job made.
pub enum Made {
    Solid(Arc<Solid>),
    Surface { solid: u64, surface: u64 },
}

impl Job {
    pub fn status(&self) -> JobStatus {
        let mut s = lock(&self.status).clone();
        if s.state == "running" || s.state == "queued" {
            s.seconds = self.started.elapsed().as_secs_f64();
        }
        s
    }

    fn update(&self, f: impl FnOnce(&mut JobStatus)) {
        f(&mut lock(&self.status));
    }

    pub fn progress(&self, stage: String, progress: f32) {
        self.update(|s| {
            s.state = "running";
            s.stage = stage;
            // Stages report their own fractions; never let the bar move backwards.
            s.progress = s.progress.max(progress.clamp(0.0, 1.0));
        });
    }
}

/// Why a request could not be queued.
#[derive(Debug)]
pub struct Busy(pub String);

/// A place in the synthesis queue; leaving it (drop) frees the place.
pub struct Ticket<'a> {
    state: &'a State,
}

impl Ticket<'_> {
    /// Wait for the work lock.
    pub fn lock(&self) -> MutexGuard<'_, ()> {
        lock(&self.state.work)
    }
}

impl Drop for Ticket<'_> {
    fn drop(&mut self) {
        self.state.queued.fetch_sub(1, Ordering::SeqCst);
    }
}

pub struct State {
    pub config: ServeConfig,
    pub compute: Compute,
    /// Held by whatever synthesizes or analyses: one job on the device at a time.
    work: Mutex<()>,
    /// Requests waiting for or holding `work` (bounded by `config.max_queued`).
    queued: AtomicUsize,
    solids: Mutex<VecDeque<Arc<Solid>>>,
    jobs: Mutex<VecDeque<Arc<Job>>>,
    /// Analyses by input hash, so a new seed of the same exemplar skips the analysis.
    analyses: Mutex<VecDeque<(u128, Arc<Analysis>)>>,
    /// Uploaded meshes and baked surfaces.
    pub surfaces: super::surfaces::Store,
    next_id: AtomicU64,
}

/// Jobs remembered for polling (finished ones are dropped oldest first).
const JOBS_KEPT: usize = 32;

impl State {
    pub fn new(config: ServeConfig, compute: Compute) -> State {
        let kept = config.max_solids;
        State {
            config,
            compute,
            work: Mutex::new(()),
            queued: AtomicUsize::new(0),
            solids: Mutex::new(VecDeque::new()),
            jobs: Mutex::new(VecDeque::new()),
            analyses: Mutex::new(VecDeque::new()),
            surfaces: super::surfaces::Store::new(kept),
            next_id: AtomicU64::new(1),
        }
    }

    /// A new id for a job, solid or surface (one sequence for all).
    pub fn next_id(&self) -> u64 {
        self.next_id.fetch_add(1, Ordering::SeqCst)
    }

    /// Take a place in the synthesis queue, or say why not.
    pub fn enqueue(&self) -> std::result::Result<Ticket<'_>, Busy> {
        let before = self.queued.fetch_add(1, Ordering::SeqCst);
        let ticket = Ticket { state: self };
        if before >= self.config.max_queued {
            return Err(Busy(format!(
                "{before} synthesis requests are already queued (limit {}); retry shortly",
                self.config.max_queued
            )));
        }
        Ok(ticket)
    }

    pub fn solid(&self, id: u64) -> Option<Arc<Solid>> {
        lock(&self.solids).iter().find(|s| s.id == id).cloned()
    }

    pub fn solids(&self) -> Vec<Arc<Solid>> {
        lock(&self.solids).iter().cloned().collect()
    }

    pub fn job(&self, id: u64) -> Option<Arc<Job>> {
        lock(&self.jobs)
            .iter()
            .find(|j| lock(&j.status).id == id)
            .cloned()
    }

    pub fn jobs(&self) -> Vec<JobStatus> {
        lock(&self.jobs).iter().map(|j| j.status()).collect()
    }

    /// Start a background job making a solid from `source` with `seed` and the server's
    /// settings; returns its status.
    pub fn start_job(
        self: &Arc<Self>,
        source: Source,
        seed: u64,
    ) -> std::result::Result<JobStatus, Busy> {
        let settings = SolidSettings {
            params: SynthParams {
                seed,
                ..self.config.params.clone()
            },
            feature_masks: FeatureMasks::Auto,
        };
        self.start_solid_job(source, settings)
    }

    /// Start a background job making a solid from `source` with `settings`.
    pub fn start_solid_job(
        self: &Arc<Self>,
        source: Source,
        settings: SolidSettings,
    ) -> std::result::Result<JobStatus, Busy> {
        let name = match &source {
            Source::Image { name, .. } | Source::Analysis { name, .. } => name.clone(),
        };
        self.spawn_job("solid", name, move |state, job| {
            state.make_solid(job, source, settings).map(Made::Solid)
        })
    }

    /// Start a background job of `kind` running `work` (a thread of its own; at most
    /// `max_jobs` queued or running); returns its status.
    pub fn spawn_job(
        self: &Arc<Self>,
        kind: &'static str,
        name: String,
        work: impl FnOnce(&State, &Arc<Job>) -> Result<Made> + Send + 'static,
    ) -> std::result::Result<JobStatus, Busy> {
        let job = {
            let mut jobs = lock(&self.jobs);
            let active = jobs
                .iter()
                .filter(|j| matches!(lock(&j.status).state, "queued" | "running"))
                .count();
            if active >= self.config.max_jobs {
                return Err(Busy(format!(
                    "{active} jobs are already running or queued (limit {}); wait for one to finish",
                    self.config.max_jobs
                )));
            }
            let id = self.next_id();
            let job = Arc::new(Job {
                status: Mutex::new(JobStatus {
                    id,
                    kind,
                    name,
                    state: "queued",
                    stage: "waiting for the device".into(),
                    progress: 0.0,
                    solid: None,
                    surface: None,
                    error: None,
                    seconds: 0.0,
                }),
                started: Instant::now(),
                cancel: CancelToken::new(),
            });
            jobs.push_back(job.clone());
            while jobs.len() > JOBS_KEPT {
                let finished = jobs
                    .iter()
                    .position(|j| matches!(lock(&j.status).state, "done" | "failed" | "cancelled"));
                match finished {
                    Some(i) => jobs.remove(i),
                    None => break,
                };
            }
            job
        };
        let status = job.status();
        let state = self.clone();
        let spawned = std::thread::Builder::new()
            .name(format!("serve-{kind}-job"))
            .spawn(move || {
                let outcome =
                    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| work(&state, &job)));
                let outcome = match outcome {
                    Ok(r) => r,
                    Err(_) => Err(Error::Gpu("the job panicked (a bug)".into())),
                };
                let seconds = job.started.elapsed().as_secs_f64();
                match outcome {
                    Ok(made) => {
                        let (solid, surface) = match made {
                            Made::Solid(solid) => {
                                tracing::info!(
                                    "job: solid {} ({}) ready in {seconds:.1} s",
                                    solid.id,
                                    solid.name
                                );
                                (solid.id, None)
                            }
                            Made::Surface { solid, surface } => {
                                tracing::info!("job: surface {surface} baked in {seconds:.1} s");
                                (solid, Some(surface))
                            }
                        };
                        job.update(|s| {
                            s.state = "done";
                            s.stage = "ready".into();
                            s.progress = 1.0;
                            s.solid = Some(solid);
                            s.surface = surface;
                            s.seconds = seconds;
                        })
                    }
                    Err(Error::Cancelled) => job.update(|s| {
                        s.state = "cancelled";
                        s.stage = "cancelled".into();
                        s.seconds = seconds;
                    }),
                    Err(e) => {
                        tracing::warn!("job failed: {}", e.report());
                        job.update(|s| {
                            s.state = "failed";
                            s.error = Some(e.report());
                            s.seconds = seconds;
                        })
                    }
                }
            });
        if let Err(e) = spawned {
            return Err(Busy(format!("cannot start a job thread: {e}")));
        }
        Ok(status)
    }

    /// Ask job `id` to stop: its synthesis ends at its next group or pass (an analysis runs to
    /// its end first), and the job ends "cancelled". `None`: no such job; `Some(Err)`: it has
    /// already finished.
    pub fn cancel_job(&self, id: u64) -> Option<std::result::Result<JobStatus, JobStatus>> {
        let job = self.job(id)?;
        let status = job.status();
        if matches!(status.state, "queued" | "running") {
            job.cancel.cancel();
            Some(Ok(job.status()))
        } else {
            Some(Err(status))
        }
    }

    /// The job's work: analysis (unless cached), then a warm synthesizer and the preview volume.
    fn make_solid(&self, job: &Job, source: Source, settings: SolidSettings) -> Result<Arc<Solid>> {
        let (name, analysis) = match source {
            Source::Analysis { name, analysis } => (name, analysis),
            Source::Image {
                name,
                image,
                periodic,
            } => {
                // The library's defaults, the command line's too (the feature channel, the
                // paper's frame for a square image), and the analysis cache's key.
                let exemplar = crate::solid::ExemplarInput {
                    images: vec![image],
                    names: vec![name.clone()],
                    periodic,
                    feature_masks: settings.feature_masks.clone(),
                    ..Default::default()
                };
                let (input, params) = exemplar.analysis_input()?;
                let key = crate::solid::cache::cache_key(&input, &params);
                let cached = lock(&self.analyses)
                    .iter()
                    .find(|(k, _)| *k == key)
                    .map(|(_, a)| a.clone());
                let analysis = match cached {
                    Some(a) => a,
                    None => {
                        let _work = lock(&self.work);
                        let analyze = || {
                            crate::lazy::analyze(&input, &params, &self.compute, &|stage, f| {
                                job.progress(format!("analysis: {stage}"), 0.7 * f)
                            })
                        };
                        // The disk cache the command line uses (same key): a restarted server
                        // reads its exemplars' analyses instead of computing them again.
                        let a = Arc::new(match &self.config.cache {
                            Some(cache) => cache.get_or_analyze(key, analyze)?,
                            None => analyze()?,
                        });
                        let mut cache = lock(&self.analyses);
                        cache.push_back((key, a.clone()));
                        if cache.len() > self.config.max_solids {
                            cache.pop_front();
                        }
                        a
                    }
                };
                (name, analysis)
            }
        };
        job.cancel.check()?;
        let _work = lock(&self.work);
        let base = job.status().progress.max(0.0);
        let params = settings.params;
        let seed = params.seed;
        // The job's token stops the preview.
        let options = SynthOptions {
            cancel: Some(job.cancel.clone()),
            ..SynthOptions::default()
        };
        let mut synth =
            Synthesizer::with_options(&analysis, params.clone(), &self.compute, options)?;
        let n = self.config.preview_size as i32;
        let preview = synth.synthesize(Box3::new([0; 3], [n; 3]), &|_, f| {
            job.progress(
                format!("synthesizing the {n}^3 preview volume"),
                base + (1.0 - base) * 0.99 * f,
            )
        })?;
        // Cancelling the finished job must not stop the solid's cuts.
        synth.set_cancel(None);
        let solid = Arc::new(Solid {
            id: self.next_id(),
            name,
            seed,
            channels: synth.color_channels(),
            analysis,
            params,
            preview: Arc::new(preview),
            session: Mutex::new(CutSession::new(synth)),
            extra: Mutex::new(None),
        });
        let mut solids = lock(&self.solids);
        solids.push_back(solid.clone());
        while solids.len() > self.config.max_solids {
            solids.pop_front();
        }
        Ok(solid)
    }

    /// A planar cut of `solid` (the caller validated the spec and holds a ticket). Returns the
    /// image and the milliseconds spent waiting for the lock and synthesizing.
    pub fn cut(
        &self,
        ticket: &Ticket,
        solid: &Solid,
        spec: &crate::lazy::cut::CutSpec,
    ) -> Result<(Image, f64, f64)> {
        let t0 = Instant::now();
        let _work = ticket.lock();
        let mut session = lock(&solid.session);
        let t1 = Instant::now();
        let img = session.cut(spec)?;
        Ok((
            img,
            (t1 - t0).as_secs_f64() * 1e3,
            t1.elapsed().as_secs_f64() * 1e3,
        ))
    }

    /// The box [0, size)^3 of `solid`: the preview, the last download, or synthesized now.
    pub fn volume(&self, ticket: &Ticket, solid: &Solid, size: u32) -> Result<Arc<Volume>> {
        if size == solid.preview.nx {
            return Ok(solid.preview.clone());
        }
        if let Some(v) = lock(&solid.extra).as_ref().filter(|v| v.nx == size) {
            return Ok(v.clone());
        }
        let _work = ticket.lock();
        let mut session = lock(&solid.session);
        let n = size as i32;
        let v = Arc::new(
            session
                .synthesizer_mut()
                .synthesize(Box3::new([0; 3], [n; 3]), &|_, _| {})?,
        );
        *lock(&solid.extra) = Some(v.clone());
        Ok(v)
    }
}

/// Decode an uploaded exemplar, refusing absurd dimensions before allocating for them.
pub fn decode_upload(bytes: &[u8], max_side: u32) -> Result<Image> {
    let what = "upload";
    let reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| Error::invalid(what, format!("cannot read the image: {e}")))?;
    let (w, h) = reader
        .into_dimensions()
        .map_err(|e| Error::invalid(what, format!("cannot decode image: {e}")))?;
    if w > max_side || h > max_side {
        return Err(Error::invalid(
            what,
            format!("image is {w}x{h}; the viewer accepts at most {max_side} pixels a side (analysis time grows with the size)"),
        ));
    }
    let img = exemplar::decode_image(bytes, what)?;
    exemplar::check_exemplar_size(&img, what)?;
    Ok(img)
}
