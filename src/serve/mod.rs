//! `solidsynth serve`: a local web viewer for the solid, and the HTTP API behind it.
//!
//! A small synchronous HTTP/1.1 server ([`http`]) with a fixed pool of worker threads. Everything that
//! synthesizes (cuts, volumes, analyses) takes one lock, `jobs::State::work`, so GPU (or CPU)
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
pub mod api_objects;
pub mod assets;
pub mod client;
pub mod http;
pub mod jobs;
pub mod query;
pub mod settings;
pub mod surfaces;

use crate::backend::Compute;
use crate::error::{Error, Result};
use crate::lazy::SynthParams;
use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::{Arc, Mutex};
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
    /// Largest surface bake resolution (voxels across the mesh's longest side).
    pub max_surface_resolution: u32,
    /// Solid parameters (seed is per request; the rest apply to every solid).
    pub params: SynthParams,
    /// Host names (with or without `:port`) accepted in requests' `Host` header besides the
    /// bound address (and, on a loopback address, `localhost`): `--allow-host`.
    pub allow_hosts: Vec<String>,
    /// Where analyses are kept between runs (the command line's cache; None: in memory only).
    pub cache: Option<crate::solid::AnalysisCache>,
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
            max_surface_resolution: 1024,
            params: SynthParams::default(),
            allow_hosts: Vec::new(),
            cache: None,
        }
    }
}

impl ServeConfig {
    pub fn validate(&self) -> Result<()> {
        self.params.validate()?;
        if !(8..=256).contains(&self.preview_size) || !self.preview_size.is_multiple_of(4) {
            return Err(Error::invalid(
                format!("--preview-size {}", self.preview_size),
                "must be a multiple of 4 in 8..=256",
            ));
        }
        if let Some(bad) = self.allow_hosts.iter().find(|h| !is_host_name(h)) {
            return Err(Error::invalid(
                format!("--allow-host {bad:?}"),
                "must be a host name, optionally NAME:PORT with a port in 1..=65535 (no spaces \
                 or slashes)",
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

/// Whether `text` is what a `Host` header may hold: a name (no spaces, slashes or control
/// characters; an IPv6 address in brackets) and optionally `:PORT`, a port in 1..=65535.
fn is_host_name(text: &str) -> bool {
    // (name, the port's text when one is given)
    let (name, port) = match text.strip_prefix('[') {
        Some(rest) => match rest.split_once(']') {
            Some((address, "")) => (address, None),
            Some((address, tail)) => match tail.strip_prefix(':') {
                Some(port) => (address, Some(port)),
                None => return false,
            },
            None => return false,
        },
        None => match text.rsplit_once(':') {
            Some((name, _)) if name.contains(':') => return false,
            Some((name, port)) => (name, Some(port)),
            None => (text, None),
        },
    };
    let port_ok = port.is_none_or(|p| {
        !p.is_empty()
            && p.bytes().all(|b| b.is_ascii_digit())
            && p.parse::<u16>().is_ok_and(|p| p > 0)
    });
    port_ok
        && !name.is_empty()
        && !name
            .chars()
            .any(|c| c.is_whitespace() || c.is_control() || c == '/')
}

/// A running server.
pub struct Server {
    state: Arc<jobs::State>,
    workers: Vec<JoinHandle<()>>,
    acceptor: Option<JoinHandle<()>>,
    stop: Arc<Mutex<bool>>,
    addr: SocketAddr,
}

impl Server {
    /// Bind and start the acceptor and the worker threads. Nothing is synthesized until asked.
    pub fn start(config: ServeConfig, compute: Compute) -> Result<Server> {
        config.validate()?;
        let want = SocketAddr::new(config.bind, config.port);
        let (listener, addr) = http::bind(want).map_err(|e| {
            Error::invalid(
                format!("--bind/--port {want}"),
                format!("cannot listen: {}", crate::error::io_problem(&e)),
            )
        })?;
        // The port actually bound (0 picks one): requests must name it in their Host header.
        let config = ServeConfig {
            port: addr.port(),
            ..config
        };
        let state = Arc::new(jobs::State::new(config, compute));
        let (tx, rx) = http::queue();
        let stop = Arc::new(Mutex::new(false));
        let spawn_err =
            |e: std::io::Error| Error::Gpu(format!("cannot start a server thread: {e}"));
        let workers = (0..state.config.workers)
            .map(|i| {
                let (rx, state) = (rx.clone(), state.clone());
                std::thread::Builder::new()
                    .name(format!("serve-worker-{i}"))
                    .spawn(move || loop {
                        // The lock is held only while waiting for the next connection.
                        let next = jobs::lock(&rx).recv();
                        let Ok(stream) = next else { return };
                        let max = state.config.max_upload_bytes;
                        http::serve_connection(stream, max, |request| api::handle(&state, request));
                    })
                    .map_err(spawn_err)
            })
            .collect::<Result<Vec<_>>>()?;
        let acceptor = {
            let stop = stop.clone();
            std::thread::Builder::new()
                .name("serve-accept".into())
                .spawn(move || http::accept_loop(listener, tx, stop))
                .map_err(spawn_err)?
        };
        Ok(Server {
            state,
            workers,
            acceptor: Some(acceptor),
            stop,
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
    pub fn join(mut self) {
        if let Some(a) = self.acceptor.take() {
            let _ = a.join();
        }
    }

    /// Stop accepting connections and wait for the workers to finish the ones they hold.
    pub fn shutdown(mut self) {
        *jobs::lock(&self.stop) = true;
        // Wake the acceptor (blocked in accept) so it sees the flag and drops the queue, which
        // ends the workers once the queue is empty.
        let _ = std::net::TcpStream::connect(self.addr);
        if let Some(a) = self.acceptor.take() {
            let _ = a.join();
        }
        for w in self.workers.drain(..) {
            let _ = w.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::is_host_name;

    #[test]
    fn allowed_hosts_are_names_with_an_optional_port() {
        for good in [
            "workstation.local",
            "h:8080",
            "[::1]",
            "[::1]:80",
            "10.0.0.2:65535",
        ] {
            assert!(is_host_name(good), "{good}");
        }
        for bad in [
            "", "h:", "h:0", "h:99999", "h:abc", "h:+80", "a b", "http://x", "a:b:c", "[::1",
            "[::1]x", "[::1]:",
        ] {
            assert!(!is_host_name(bad), "{bad}");
        }
    }
}
