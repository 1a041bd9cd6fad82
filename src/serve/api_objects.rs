//! The object view's endpoints: meshes (the built-in bunny, uploads), surface bakes and their
//! `.glb`s, and job cancellation. Validation as in `super::api`: 400 naming the parameter, 404
//! for what the server does not hold, 409 for a job already finished.

use super::api::{from_error, parse_id, solid_of, Answer, Query, Reply};
use super::jobs::{Busy, State};
use super::surfaces::{self, RESOLUTIONS};
use std::sync::Arc;

/// Answer `segments` if they are one of these endpoints (None: not ours).
pub fn route(
    state: &Arc<State>,
    method: &str,
    segments: &[&str],
    query: &Query,
    body: &[u8],
) -> Option<Answer> {
    let get = method == "GET" || method == "HEAD";
    let post = method == "POST";
    Some(match (segments, get, post) {
        (["api", "meshes"], true, _) => query.only(&[]).map(|()| {
            let list: Vec<_> = state.surfaces.meshes().iter().map(|m| m.info()).collect();
            Reply::json(200, serde_json::json!(list))
        }),
        (["api", "meshes"], _, true) => add_mesh(state, query, body),
        (["api", "meshes", id], true, _) => mesh_of(state, id).map(|m| Reply::json(200, m.info())),
        (["api", "meshes", id, "geometry"], true, _) => {
            mesh_of(state, id).map(|m| Reply::bytes("application/octet-stream", m.geometry()))
        }
        (["api", "solids", id, "surface"], _, true) => {
            solid_of(state, id).and_then(|s| start_bake(state, s, query))
        }
        (["api", "surfaces"], true, _) => query.only(&[]).map(|()| {
            let list: Vec<_> = state.surfaces.surfaces().iter().map(|s| s.info()).collect();
            Reply::json(200, serde_json::json!(list))
        }),
        (["api", "surfaces", file], true, _) => surface_file(state, file),
        (["api", "jobs", id, "cancel"], _, true) => cancel(state, id),
        _ => return None,
    })
}

/// Whether `segments` name one of these endpoints (for 405 on the wrong method).
pub fn known_path(segments: &[&str]) -> bool {
    matches!(
        segments,
        ["api", "meshes" | "surfaces"]
            | ["api", "meshes" | "surfaces", _]
            | ["api", "meshes", _, "geometry"]
            | ["api", "solids", _, "surface"]
            | ["api", "jobs", _, "cancel"]
    )
}

fn mesh_of(state: &State, id: &str) -> Result<Arc<surfaces::StoredMesh>, (u16, String)> {
    state.surfaces.mesh(id).ok_or_else(|| {
        (
            404,
            format!("no mesh {id:?} (`bunny`, or an upload still kept: the newest few are)"),
        )
    })
}

/// POST /api/meshes?format=obj|ply|glb|gltf[&name=N]: the mesh in the body (the upload limit
/// applies).
fn add_mesh(state: &State, q: &Query, body: &[u8]) -> Answer {
    q.only(&["format", "name"])?;
    let format = q
        .get("format")
        .ok_or((400, "missing format=obj|ply|glb|gltf".to_string()))?;
    if body.is_empty() {
        return Err((400, "the mesh goes in the request body".into()));
    }
    let name = q.get("name").unwrap_or("upload");
    if name.len() > 128 || name.chars().any(char::is_control) {
        return Err((400, "invalid name: at most 128 printable characters".into()));
    }
    let mesh = state
        .surfaces
        .add_mesh(body, format, name)
        .map_err(from_error)?;
    Ok(Reply::json(201, mesh.info()))
}

/// POST /api/solids/ID/surface?mesh=bunny|ID&resolution=R[&fast=1]: a bake job.
fn start_bake(state: &Arc<State>, solid: Arc<super::jobs::Solid>, q: &Query) -> Answer {
    q.only(&["mesh", "resolution", "fast"])?;
    let mesh = mesh_of(state, q.get("mesh").unwrap_or("bunny"))?;
    let resolution = q
        .u64_in(
            "resolution",
            *RESOLUTIONS.start() as u64,
            (*RESOLUTIONS.end()).min(state.config.max_surface_resolution) as u64,
        )?
        .unwrap_or(256) as u32;
    let fast = q.bool("fast")?;
    match surfaces::start_bake(state, solid, mesh, resolution, fast) {
        Ok(status) => Ok(Reply::json(202, serde_json::json!(status))),
        Err(Busy(m)) => Err((503, m)),
    }
}

/// GET /api/surfaces/ID.glb (the textured model, as a download) or /api/surfaces/ID (its
/// summary).
fn surface_file(state: &State, file: &str) -> Answer {
    let (id, glb) = match file.strip_suffix(".glb") {
        Some(id) => (id, true),
        None => (file, false),
    };
    let surface = state
        .surfaces
        .surface(parse_id(id)?)
        .ok_or_else(|| (404, format!("no surface {id} (the newest few are kept)")))?;
    if !glb {
        return Ok(Reply::json(200, surface.info()));
    }
    let name = format!(
        "solid-{}-{}-{}.glb",
        surface.solid, surface.mesh, surface.resolution
    );
    Ok(
        Reply::bytes("model/gltf-binary", surface.glb.clone()).header(
            "Content-Disposition",
            format!("attachment; filename=\"{name}\""),
        ),
    )
}

/// POST /api/jobs/ID/cancel.
fn cancel(state: &State, id: &str) -> Answer {
    let id = parse_id(id)?;
    match state.cancel_job(id) {
        None => Err((404, format!("no job {id}"))),
        Some(Ok(status)) => Ok(Reply::json(200, serde_json::json!(status))),
        Some(Err(status)) => Err((
            409,
            format!("job {id} has already ended ({})", status.state),
        )),
    }
}
