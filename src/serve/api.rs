//! Routing and parameter validation. Every answer is JSON (errors: `{"error": MESSAGE}`), a PNG
//! or a volume file; bad parameters get 400 naming the parameter, unknown paths 404, a wrong
//! method 405, an oversized upload 413, a full queue 503. A handler that panics (a bug) answers
//! 500 and the worker goes on serving.

use super::assets;
use super::http::{Request, Response};
use super::jobs::{self, Source, State};
pub use super::query::Query;
use crate::error::Error;
use crate::lazy::cut::CutSpec;
use std::sync::Arc;
use std::time::Instant;

/// A response before it is sent.
pub struct Reply {
    pub status: u16,
    pub content_type: &'static str,
    pub body: Vec<u8>,
    pub headers: Vec<(String, String)>,
}

impl Reply {
    pub fn json(status: u16, value: serde_json::Value) -> Reply {
        Reply {
            status,
            content_type: "application/json",
            body: value.to_string().into_bytes(),
            headers: vec![],
        }
    }

    pub fn error(status: u16, message: impl Into<String>) -> Reply {
        Reply::json(status, serde_json::json!({"error": message.into()}))
    }

    pub(super) fn bytes(content_type: &'static str, body: Vec<u8>) -> Reply {
        Reply {
            status: 200,
            content_type,
            body,
            headers: vec![],
        }
    }

    pub(super) fn header(mut self, name: &str, value: impl Into<String>) -> Reply {
        self.headers.push((name.into(), value.into()));
        self
    }
}

/// Answer one request (called by a worker thread with the request read whole).
pub fn handle(state: &Arc<State>, request: Request) -> Response {
    let start = Instant::now();
    let reply = match check_sender(&state.config, &request) {
        Err(refused) => refused,
        Ok(()) => std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| route(state, &request)))
            .unwrap_or_else(|_| Reply::error(500, "internal error (a bug); the server goes on")),
    };
    tracing::debug!(
        "{} {} -> {} in {:.1} ms",
        request.method,
        request.target,
        reply.status,
        start.elapsed().as_secs_f64() * 1e3
    );
    Response {
        status: reply.status,
        content_type: reply.content_type,
        headers: reply.headers,
        body: reply.body,
    }
}

/// The hosts a request may name in its `Host` header: the bound address with its port, and on a
/// loopback address `localhost` and the other loopback spellings; plus `--allow-host` names
/// (with the port, or without it for any port).
fn host_allowed(config: &super::ServeConfig, host: &str) -> bool {
    let host = host.to_ascii_lowercase();
    let port = config.port;
    let bound = match config.bind {
        std::net::IpAddr::V4(ip) => format!("{ip}:{port}"),
        std::net::IpAddr::V6(ip) => format!("[{ip}]:{port}"),
    };
    if host == bound {
        return true;
    }
    if config.bind.is_loopback()
        && [
            format!("localhost:{port}"),
            format!("127.0.0.1:{port}"),
            format!("[::1]:{port}"),
        ]
        .contains(&host)
    {
        return true;
    }
    config.allow_hosts.iter().any(|allowed| {
        let allowed = allowed.to_ascii_lowercase();
        host == allowed || host == format!("{allowed}:{port}")
    })
}

/// Refuse a request from where the server is not meant to be reached: a `Host` it does not
/// answer to (421: DNS rebinding, a page on another name reading the API), a state-changing
/// request whose `Origin` is another site's (403: cross-site requests), an upload that is not
/// an image or a mesh (415).
fn check_sender(config: &super::ServeConfig, request: &Request) -> Result<(), Reply> {
    let Some(host) = request.header("host") else {
        return Err(Reply::error(400, "the request has no Host header"));
    };
    if !host_allowed(config, host) {
        return Err(Reply::error(
            421,
            format!(
                "this server does not answer to host {host}: it answers to its address with its \
                 port ({}:{}) and the names --allow-host gives",
                config.bind, config.port
            ),
        ));
    }
    let changes_state = !matches!(request.method.as_str(), "GET" | "HEAD" | "OPTIONS");
    if changes_state {
        if let Some(origin) = request.header("origin") {
            let own = origin
                .strip_prefix("http://")
                .is_some_and(|o| o.eq_ignore_ascii_case(host));
            if !own {
                return Err(Reply::error(
                    403,
                    format!("requests from origin {origin} may not change this server's state"),
                ));
            }
        }
        // (Neither is a type a cross-site form can send without a preflight.)
        if !request.body.is_empty() {
            let accepted = request.header("content-type").is_some_and(|t| {
                let t = t.trim().to_ascii_lowercase();
                t.starts_with("image/") || t.starts_with("model/")
            });
            if !accepted {
                return Err(Reply::error(
                    415,
                    "an upload must be an image (Content-Type: image/png, image/jpeg, ...) or a \
                     mesh (model/obj, model/ply, model/gltf-binary, ...)",
                ));
            }
        }
    }
    Ok(())
}

fn route(state: &Arc<State>, request: &Request) -> Reply {
    let (path, query) = request
        .target
        .split_once('?')
        .unwrap_or((&request.target, ""));
    let method = request.method.as_str();
    let segments: Vec<&str> = path.trim_start_matches('/').split('/').collect();
    let get = method == "GET" || method == "HEAD";
    let query = match Query::parse(query) {
        Ok(q) => q,
        Err(e) => return Reply::error(400, e),
    };
    if let Some(answer) = super::api_objects::route(state, method, &segments, &query, &request.body)
    {
        return answer.unwrap_or_else(|(status, message)| Reply::error(status, message));
    }
    // Of these endpoints only new solids, cuts and volumes take parameters; elsewhere in the API
    // one is a mistake. (Pages ignore theirs.)
    let takes_parameters = matches!(
        segments.as_slice(),
        ["api", "solids"] | ["api", "solids", _, "cut" | "volume"]
    );
    if segments.first() == Some(&"api") && !takes_parameters {
        if let Err((status, message)) = query.only(&[]) {
            return Reply::error(status, message);
        }
    }
    let result = match (segments.as_slice(), get) {
        (["api", "health"], true) => Ok(Reply::json(200, serde_json::json!({"ok": true}))),
        (["api", "state"], true) => Ok(state_json(state)),
        (["api", "exemplars"], true) => Ok(exemplars_json()),
        (["api", "exemplars", file], true) => exemplar_png(file),
        (["api", "solids"], false) if method == "POST" => new_solid(state, &request.body, &query),
        (["api", "jobs", id], true) => parse_id(id).and_then(|id| {
            state
                .job(id)
                .map(|j| Reply::json(200, serde_json::json!(j.status())))
                .ok_or_else(|| (404, format!("no job {id}")))
        }),
        (["api", "solids", id], true) => solid_of(state, id).map(|s| Reply::json(200, s.info())),
        (["api", "solids", id, "cut"], true) => {
            solid_of(state, id).and_then(|s| cut(state, &s, &query))
        }
        (["api", "solids", id, "volume"], true) => {
            solid_of(state, id).and_then(|s| volume(state, &s, &query))
        }
        (["api", ..], _)
            if known_api_path(&segments) || super::api_objects::known_path(&segments) =>
        {
            Err((405, format!("{method} is not allowed on {path}")))
        }
        (["api", ..], _) => Err((404, format!("no API endpoint {path}"))),
        (_, true) => match assets::get(path) {
            Some(a) => Ok(Reply::bytes(a.content_type, a.body.to_vec())),
            None => Err((404, format!("no page {path}"))),
        },
        (_, false) => Err((405, format!("{method} is not allowed on {path}"))),
    };
    result.unwrap_or_else(|(status, message)| Reply::error(status, message))
}

pub(super) type Answer = Result<Reply, (u16, String)>;

fn known_api_path(segments: &[&str]) -> bool {
    matches!(
        segments,
        ["api", "health" | "state" | "exemplars" | "solids"]
            | ["api", "exemplars" | "jobs" | "solids", _]
            | ["api", "solids", _, "cut" | "volume"]
    )
}

pub(super) fn parse_id(text: &str) -> Result<u64, (u16, String)> {
    text.parse::<u64>()
        .map_err(|_| (404, format!("{text:?} is not an id")))
}

pub(super) fn solid_of(
    state: &State,
    id: &str,
) -> Result<std::sync::Arc<jobs::Solid>, (u16, String)> {
    let id = parse_id(id)?;
    state.solid(id).ok_or_else(|| {
        (
            404,
            format!(
                "no solid {id} (solids are kept while newer ones come: at most {})",
                state.config.max_solids
            ),
        )
    })
}

/// A library error: the caller's input (400) or ours (500).
pub(super) fn from_error(e: Error) -> (u16, String) {
    (if e.is_user_error() { 400 } else { 500 }, e.report())
}

fn state_json(state: &State) -> Reply {
    let c = &state.config;
    Reply::json(
        200,
        serde_json::json!({
            "solids": state.solids().iter().map(|s| s.info()).collect::<Vec<_>>(),
            "jobs": state.jobs(),
            "backend": state.compute.describe(),
            "limits": {
                "max_cut_size": c.max_cut_size, "max_volume_size": c.max_volume_size,
                "preview_size": c.preview_size, "max_upload_bytes": c.max_upload_bytes,
                "max_upload_side": c.max_upload_side, "max_queued": c.max_queued,
            },
        }),
    )
}

fn exemplars_json() -> Reply {
    let list: Vec<_> = jobs::BUILTINS
        .iter()
        .map(|b| serde_json::json!({"name": b.name, "description": b.description}))
        .collect();
    Reply::json(200, serde_json::json!(list))
}

fn exemplar_png(file: &str) -> Answer {
    let b = file
        .strip_suffix(".png")
        .and_then(jobs::builtin)
        .ok_or_else(|| (404, format!("no built-in exemplar {file}")))?;
    let png = crate::io::atomic::png_bytes(&b.image().to_rgba8()).map_err(from_error)?;
    Ok(Reply::bytes("image/png", png))
}

/// POST /api/solids: a built-in (`?exemplar=NAME`) or the uploaded image in the body.
fn new_solid(state: &Arc<State>, body: &[u8], q: &Query) -> Answer {
    let mut known = vec!["exemplar", "periodic"];
    known.extend_from_slice(super::settings::SOLID_PARAMETERS);
    q.only(&known)?;
    let settings = super::settings::solid_settings(&state.config.params, q)?;
    // The transport refused bodies over `max_upload_bytes` (413) before reading them.
    let source = match (q.get("exemplar"), body.is_empty()) {
        (Some(name), true) => {
            let b = jobs::builtin(name).ok_or_else(|| {
                (
                    400,
                    format!(
                        "invalid exemplar {name:?}: built-ins are {}",
                        jobs::BUILTINS
                            .iter()
                            .map(|b| b.name)
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                )
            })?;
            if q.get("periodic").is_some() {
                return Err((400, "periodic applies to uploads (built-ins tile)".into()));
            }
            Source::Image {
                name: b.name.into(),
                image: b.image(),
                periodic: true,
            }
        }
        (None, false) => Source::Image {
            name: "upload".into(),
            image: jobs::decode_upload(body, state.config.max_upload_side).map_err(from_error)?,
            periodic: q.bool("periodic")?,
        },
        (Some(_), false) => {
            return Err((
                400,
                "give either ?exemplar=NAME or an image body, not both".into(),
            ))
        }
        (None, true) => {
            return Err((
                400,
                "give ?exemplar=NAME or an image (PNG, JPEG, ...) as the body".into(),
            ))
        }
    };
    match state.start_solid_job(source, settings) {
        Ok(status) => Ok(Reply::json(202, serde_json::json!(status))),
        Err(jobs::Busy(m)) => Err((503, m)),
    }
}

/// GET /api/solids/ID/cut: the cut as a PNG; latency in headers.
fn cut(state: &State, solid: &jobs::Solid, q: &Query) -> Answer {
    q.only(&["origin", "normal", "up", "size", "spacing"])?;
    let max = state.config.max_cut_size;
    let size = q.u64_in("size", 1, max as u64)?.unwrap_or(128) as u32;
    let spacing = q.f64_in("spacing", 1.0 / 64.0, 64.0)?.unwrap_or(1.0);
    if size as f64 * spacing > max as f64 {
        return Err((
            400,
            format!(
                "invalid size x spacing = {}: a cut spans at most {max} voxels a side",
                size as f64 * spacing
            ),
        ));
    }
    let origin = q
        .triple("origin")?
        .ok_or((400, "missing origin=X,Y,Z".to_string()))?;
    if origin.iter().any(|c| c.abs() > 1e6) {
        return Err((
            400,
            "invalid origin: coordinates must lie within +-1e6 voxels".into(),
        ));
    }
    let normal = q
        .triple("normal")?
        .ok_or((400, "missing normal=NX,NY,NZ".to_string()))?;
    let len = normal.iter().map(|c| c * c).sum::<f64>().sqrt();
    if (len - 1.0).abs() > NORMAL_TOLERANCE {
        return Err((
            400,
            format!("invalid normal: must be a unit vector (its length is {len}; tolerance {NORMAL_TOLERANCE})"),
        ));
    }
    let spec = CutSpec {
        origin,
        normal,
        up: q.triple("up")?,
        size,
        spacing,
    };
    // The frame's checks name the command line's flags; here they are parameters.
    let (u, v, n) = spec.frame().map_err(|e| match e {
        crate::Error::InvalidInput { what, problem } => (
            400,
            format!("invalid {}: {problem}", what.trim_start_matches("--")),
        ),
        other => from_error(other),
    })?;
    let ticket = state.enqueue().map_err(|jobs::Busy(m)| (503, m))?;
    let (img, queue_ms, synth_ms) = state.cut(&ticket, solid, &spec).map_err(from_error)?;
    drop(ticket);
    let t = Instant::now();
    let png = crate::io::atomic::png_bytes(&img.to_rgba8()).map_err(from_error)?;
    let encode_ms = t.elapsed().as_secs_f64() * 1e3;
    let frame = serde_json::json!({"u": u.to_array(), "v": v.to_array(), "n": n.to_array()});
    Ok(Reply::bytes("image/png", png)
        .header("X-Synthesis-Ms", format!("{synth_ms:.2}"))
        .header("X-Queue-Ms", format!("{queue_ms:.2}"))
        .header("X-Encode-Ms", format!("{encode_ms:.2}"))
        .header("X-Cut-Frame", frame.to_string()))
}

/// How far from 1 a normal's length may be. Normals are rejected rather than normalized, so a
/// client that sends a wrong vector learns about it instead of getting another plane.
pub const NORMAL_TOLERANCE: f64 = 1e-3;

/// GET /api/solids/ID/volume: the box [0, size)^3 in one of the formats the command line
/// writes (`nrrd`, `nrrd-gzip`, `npy`, `tiff`, `ktx2`, `vdb`, `vti`, `flipbook` PNG), or `raw` RGBA
/// bytes.
fn volume(state: &State, solid: &jobs::Solid, q: &Query) -> Answer {
    use crate::io::volume_file::{VolumeFormat, VolumeOutput};
    q.only(&["size", "format"])?;
    let max = state.config.max_volume_size;
    let size = q
        .u64_in("size", 8, max as u64)?
        .unwrap_or(state.config.preview_size as u64) as u32;
    let format = q.get("format").unwrap_or("nrrd");
    let file_format = match format {
        "nrrd" => Some(VolumeFormat::Nrrd),
        "nrrd-gzip" => Some(VolumeFormat::NrrdGzip),
        "npy" => Some(VolumeFormat::Npy),
        "tiff" => Some(VolumeFormat::Tiff),
        "ktx2" => Some(VolumeFormat::Ktx2),
        "vdb" => Some(VolumeFormat::Vdb),
        "vti" => Some(VolumeFormat::Vti),
        "flipbook" => Some(VolumeFormat::Png),
        "raw" => None,
        _ => {
            return Err((
                400,
                format!(
                    "invalid format {format:?}: nrrd, nrrd-gzip, npy, tiff, ktx2, vdb, vti, flipbook or raw"
                ),
            ))
        }
    };
    let ticket = state.enqueue().map_err(|jobs::Busy(m)| (503, m))?;
    let v = state.volume(&ticket, solid, size).map_err(from_error)?;
    drop(ticket);
    let name = format!("solid-{}-{size}", solid.id);
    let (content_type, body, ext) = match file_format {
        Some(format) => {
            let output = VolumeOutput {
                format,
                texture: Default::default(),
                vdb: Default::default(),
            };
            let body = crate::io::volume_file::to_bytes(&v, output).map_err(from_error)?;
            let (content_type, ext) = match format {
                VolumeFormat::Nrrd | VolumeFormat::NrrdGzip => ("application/octet-stream", "nrrd"),
                VolumeFormat::Npy => ("application/octet-stream", "npy"),
                VolumeFormat::Tiff => ("image/tiff", "tif"),
                VolumeFormat::Ktx2 => ("image/ktx2", "ktx2"),
                VolumeFormat::Vdb => ("application/octet-stream", "vdb"),
                VolumeFormat::Vti => ("application/xml", "vti"),
                VolumeFormat::Png => ("image/png", "png"),
            };
            (content_type, body, ext)
        }
        None => (
            "application/octet-stream",
            crate::io::flipbook::rgba_bytes(&v),
            "rgba",
        ),
    };
    Ok(Reply::bytes(content_type, body)
        .header("X-Volume-Size", size.to_string())
        .header(
            "Content-Disposition",
            format!("attachment; filename=\"{name}.{ext}\""),
        ))
}
