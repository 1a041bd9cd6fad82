//! `solidsynth serve`: a local web viewer for the solid, and the HTTP API behind it.
//!
//! One synchronous HTTP server (`tiny_http`) with a fixed pool of worker threads. Everything that
//! synthesizes (cuts, volumes, analyses) takes one lock, [`jobs::State::work`], so GPU (or CPU)
//! work is serialized and concurrent requests queue behind it instead of competing for the device;
//! the number of requests allowed to queue is bounded ([`ServeConfig::max_queued`]) and the
//! surplus gets HTTP 503 at once, so neither threads nor memory pile up. Analyses of new
//! exemplars run in background jobs the page polls, never on a worker thread.
//!
//! Modules: [`api`] routes requests and validates parameters, [`assets`] holds the page (embedded
//! in the binary: only names in its table are served, so no path can reach the file system),
//! [`jobs`] holds the solids and the background jobs, [`client`] is a minimal HTTP/1.1 client
//! for the tests and the load benchmark.

pub mod api;
pub mod assets;
pub mod client;
pub mod jobs;

use crate::backend::Compute;
use crate::error::{Error, Result};
use crate::lazy::SynthParams;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::Arc;
use std::thread::JoinHandle;

/// Server settings; the defaults are what `solidsynth serve` uses.
#[derive(Clone, Debug)]
pub struct ServeConfig {
    pub bind: IpAddr,
    /// 0 picks a free port.
    pub port: u16,
    /// Worker threads answering requests. More than `max_queued`, so cheap requests (the page,
    /// job polls) are still answered while synthesis requests wait for the lock.
    pub workers: usize,
    /// Synthesis requests allowed to wait for (or hold) the work lock; more get HTTP 503.
    pub max_queued: usize,
    /// Largest upload body (bytes).
    pub max_upload_bytes: usize,
    /// Largest uploaded exemplar side (pixels): the analysis cost grows with it.
    pub max_upload_side: u32,
    /// Largest cut: pixels per side, and also voxels spanned per side (size x spacing), which
    /// bounds the bricks a cut can make the synthesizer hold.
    pub max_cut_size: u32,
    /// Largest volume edge served for download or display.
    pub max_volume_size: u32,
    /// Edge of the volume synthesized with every solid (the page's 3D texture and slices).
    pub preview_size: u32,
    /// Solids kept (oldest dropped first).
    pub max_solids: usize,
    /// Background jobs running or queued at once; more get HTTP 503.
    pub max_jobs: usize,
    /// Solid parameters (seed is per request; the rest apply to every solid).
    pub params: SynthParams,
}

impl Default for ServeConfig {
    fn default() -> Self {
        ServeConfig {
            bind: IpAddr::V4(Ipv4Addr::LOCALHOST),
            port: 8080,
            workers: 16,
            max_queued: 12,
            max_upload_bytes: 16 << 20,
            max_upload_side: 512,
            max_cut_size: 512,
            max_volume_size: 128,
            preview_size: 64,
            max_solids: 4,
            max_jobs: 2,
            params: SynthParams::default(),
        }
    }
}

impl ServeConfig {
    pub fn validate(&self) -> Result<()> {
        self.params.validate()?;
        if !(8..=256).contains(&self.preview_size) || self.preview_size % 4 != 0 {
            return Err(Error::invalid(
                format!("--preview-size {}", self.preview_size),
                "must be a multiple of 4 in 8..=256",
            ));
        }
        if self.workers <= self.max_queued || self.max_queued == 0 {
            return Err(Error::invalid(
                "workers",
                "need more worker threads than queued synthesis requests, and a queue of at least 1",
            ));
        }
        Ok(())
    }
}

/// A running server.
pub struct Server {
    http: Arc<tiny_http::Server>,
    state: Arc<jobs::State>,
    workers: Vec<JoinHandle<()>>,
    addr: SocketAddr,
}

impl Server {
    /// Bind and start the worker threads. Nothing is synthesized until asked for.
    pub fn start(config: ServeConfig, compute: Compute) -> Result<Server> {
        config.validate()?;
        let want = SocketAddr::new(config.bind, config.port);
        let http = tiny_http::Server::http(want).map_err(|e| {
            Error::invalid(
                format!("--bind/--port {want}"),
                format!("cannot listen: {e}"),
            )
        })?;
        let addr = http
            .server_addr()
            .to_ip()
            .ok_or_else(|| Error::invalid("--bind", "not an IP address"))?;
        let http = Arc::new(http);
        let state = Arc::new(jobs::State::new(config, compute));
        let workers = (0..state.config.workers)
            .map(|i| {
                let (http, state) = (http.clone(), state.clone());
                std::thread::Builder::new()
                    .name(format!("serve-worker-{i}"))
                    .spawn(move || {
                        // recv() fails only when the server is unblocked (shut down).
                        while let Ok(request) = http.recv() {
                            api::handle(&state, request);
                        }
                    })
                    .map_err(|e| Error::Gpu(format!("cannot start a worker thread: {e}")))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Server {
            http,
            state,
            workers,
            addr,
        })
    }

    /// The address actually bound (the port is known even when 0 was asked for).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    pub fn state(&self) -> &Arc<jobs::State> {
        &self.state
    }

    /// Serve until the process ends.
    pub fn join(self) {
        for w in self.workers {
            let _ = w.join();
        }
    }

    /// Stop accepting requests and wait for the workers to finish the ones they hold.
    pub fn shutdown(self) {
        for _ in 0..self.workers.len() {
            self.http.unblock();
        }
        for w in self.workers {
            let _ = w.join();
        }
    }
}
