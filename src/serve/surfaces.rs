//! Meshes and surface bakes for the viewer's object view: the built-in Stanford bunny and
//! uploaded meshes (OBJ, PLY, glTF), and jobs that bake a solid onto one at a chosen resolution
//! (the engine's `surface` path: only the voxels the surface passes through are synthesized) into
//! a textured `.glb` the page loads and offers for download.
//!
//! Bakes do not take the synthesis lock that cuts and volumes queue on (one bake runs at a time
//! under a lock of its own), so a cut is answered while a bake runs instead of after it.

use super::jobs::{lock, Busy, Job, JobStatus, Made, Solid, State};
use crate::error::{Error, Result};
use crate::mesh::{self, Mesh};
use crate::solid::surface::{AtlasLayout, SurfacePlan};
use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

/// A mesh the page can bake onto.
pub struct StoredMesh {
    /// `bunny`, or the number the upload got.
    pub id: String,
    pub name: String,
    pub mesh: Mesh,
}

impl StoredMesh {
    pub fn info(&self) -> serde_json::Value {
        serde_json::json!({"id": self.id, "name": self.name,
            "vertices": self.mesh.positions.len(), "triangles": self.mesh.triangles.len(),
            "has_uvs": self.mesh.uvs.is_some()})
    }

    /// The geometry for the page: u32 vertex count V, u32 triangle count T (little endian),
    /// V x 3 f32 positions centred and scaled so the longest side spans 1 (as the bake places
    /// the mesh: its bounds' box), T x 3 u32 indices.
    pub fn geometry(&self) -> Vec<u8> {
        let (lo, hi) = self.mesh.bounds();
        let extent = (hi - lo).max_element().max(f64::MIN_POSITIVE);
        let centre = (lo + hi) * 0.5;
        let m = &self.mesh;
        let mut out = Vec::with_capacity(8 + m.positions.len() * 12 + m.triangles.len() * 12);
        out.extend_from_slice(&(m.positions.len() as u32).to_le_bytes());
        out.extend_from_slice(&(m.triangles.len() as u32).to_le_bytes());
        for p in &m.positions {
            for k in 0..3 {
                let c = (p[k] as f64 - centre[k]) / extent;
                out.extend_from_slice(&(c as f32).to_le_bytes());
            }
        }
        for t in &m.triangles {
            for i in t {
                out.extend_from_slice(&i.to_le_bytes());
            }
        }
        out
    }
}

/// A finished bake.
pub struct Surface {
    pub id: u64,
    pub solid: u64,
    pub mesh: String,
    pub resolution: u32,
    pub fast: bool,
    pub atlas: [u32; 2],
    pub seconds: f64,
    pub glb: Vec<u8>,
}

impl Surface {
    pub fn info(&self) -> serde_json::Value {
        serde_json::json!({"id": self.id, "solid": self.solid, "mesh": self.mesh,
            "resolution": self.resolution, "fast": self.fast, "atlas": self.atlas,
            "seconds": self.seconds, "bytes": self.glb.len(),
            "glb": format!("/api/surfaces/{}.glb", self.id)})
    }
}

/// The uploaded meshes and finished bakes the server keeps (the newest `kept` of each), and the
/// lock one bake at a time holds.
pub struct Store {
    meshes: Mutex<VecDeque<Arc<StoredMesh>>>,
    surfaces: Mutex<VecDeque<Arc<Surface>>>,
    bake: Mutex<()>,
    next_mesh: std::sync::atomic::AtomicU64,
    kept: usize,
}

/// The Stanford bunny (`assets/meshes/bunny.obj`), parsed once.
fn bunny() -> Arc<StoredMesh> {
    static BUNNY: std::sync::OnceLock<Arc<StoredMesh>> = std::sync::OnceLock::new();
    BUNNY
        .get_or_init(|| {
            let mesh =
                mesh::parse_obj(mesh::BUNNY_OBJ, "bunny.obj").expect("the built-in bunny parses");
            Arc::new(StoredMesh {
                id: "bunny".into(),
                name: "Stanford bunny".into(),
                mesh,
            })
        })
        .clone()
}

/// Resolutions a bake may ask for.
pub const RESOLUTIONS: std::ops::RangeInclusive<u32> = 16..=2048;

impl Store {
    pub fn new(kept: usize) -> Store {
        Store {
            meshes: Mutex::new(VecDeque::new()),
            surfaces: Mutex::new(VecDeque::new()),
            bake: Mutex::new(()),
            next_mesh: std::sync::atomic::AtomicU64::new(1),
            kept: kept.max(1),
        }
    }

    /// `bunny` or an uploaded mesh still kept.
    pub fn mesh(&self, id: &str) -> Option<Arc<StoredMesh>> {
        if id == "bunny" {
            return Some(bunny());
        }
        lock(&self.meshes).iter().find(|m| m.id == id).cloned()
    }

    pub fn meshes(&self) -> Vec<Arc<StoredMesh>> {
        let mut all = vec![bunny()];
        all.extend(lock(&self.meshes).iter().cloned());
        all
    }

    /// Parse, check and keep an uploaded mesh of `format` (`obj`, `ply`, `glb`; `gltf` with
    /// its buffers embedded).
    pub fn add_mesh(&self, bytes: &[u8], format: &str, name: &str) -> Result<Arc<StoredMesh>> {
        // (One mesh a request: the request's own body, whatever name it is stored under.)
        let what = format!("uploaded {format} mesh");
        let mesh = match format {
            "obj" => mesh::parse_obj(bytes, &what)?,
            "ply" => mesh::parse_ply(bytes, &what)?,
            "glb" | "gltf" => mesh::gltf_in::parse_gltf(bytes, &what, None)?,
            _ => {
                return Err(Error::invalid(
                    format!("format {format:?}"),
                    "meshes are obj, ply, glb or gltf",
                ))
            }
        };
        mesh.validate(&what)?;
        let id = self
            .next_mesh
            .fetch_add(1, std::sync::atomic::Ordering::SeqCst)
            .to_string();
        let stored = Arc::new(StoredMesh {
            id,
            name: name.to_string(),
            mesh,
        });
        let mut meshes = lock(&self.meshes);
        meshes.push_back(stored.clone());
        while meshes.len() > self.kept {
            meshes.pop_front();
        }
        Ok(stored)
    }

    pub fn surface(&self, id: u64) -> Option<Arc<Surface>> {
        lock(&self.surfaces).iter().find(|s| s.id == id).cloned()
    }

    pub fn surfaces(&self) -> Vec<Arc<Surface>> {
        lock(&self.surfaces).iter().cloned().collect()
    }

    fn keep(&self, surface: Arc<Surface>) {
        let mut surfaces = lock(&self.surfaces);
        surfaces.push_back(surface);
        while surfaces.len() > self.kept {
            surfaces.pop_front();
        }
    }
}

/// Start a job baking `solid` onto `mesh` with the mesh's longest side spanning `resolution`
/// voxels; `fast`: two passes at the finest level and a coarse-level cache (a slightly different
/// solid, labelled so on the page).
pub fn start_bake(
    state: &Arc<State>,
    solid: Arc<Solid>,
    mesh: Arc<StoredMesh>,
    resolution: u32,
    fast: bool,
) -> std::result::Result<JobStatus, Busy> {
    let name = format!(
        "{} on {} at {resolution}{}",
        solid.name,
        mesh.name,
        if fast { " (fast)" } else { "" }
    );
    state.spawn_job("surface", name, move |state, job| {
        bake(state, job, &solid, &mesh, resolution, fast)
    })
}

fn bake(
    state: &State,
    job: &Arc<Job>,
    solid: &Solid,
    mesh: &StoredMesh,
    resolution: u32,
    fast: bool,
) -> Result<Made> {
    job.progress("waiting for the bake before it".into(), 0.0);
    let _one_bake = lock(&state.surfaces.bake);
    job.cancel.check()?;
    let start = std::time::Instant::now();
    let mut params = solid.params.clone();
    if fast {
        params.passes = "2,2,2,1".parse().expect("a valid schedule");
        params.coarse_cache = params.coarse_cache.or(Some(128));
    }
    let group = match state.compute {
        crate::backend::Compute::Cpu => crate::lazy::memory::HOST_MEMORY_GROUP,
        _ => crate::lazy::memory::LARGEST_GROUP,
    };
    let layout = AtlasLayout::TexelSize {
        size: None,
        gutter: 0,
    };
    let plan = SurfacePlan::new(
        &mesh.mesh,
        &mesh.name,
        resolution,
        layout,
        params.coarse_cache,
        group,
    )?;
    let reporter = job.clone();
    let mut facade = crate::solid::Solid::builder()
        .shared_analysis(solid.analysis.clone())
        .params(params)
        .compute(state.compute.clone())
        .cancel(job.cancel.clone())
        .progress(move |stage, f| reporter.progress(format!("baking: {stage}"), 0.95 * f))
        .build()?;
    let baked = facade.bake_surface(&mesh.mesh, &plan)?;
    drop(facade);
    job.progress("encoding the texture".into(), 0.96);
    let png = baked.png()?;
    drop(baked);
    let glb = mesh::glb::glb_bytes(&mesh.mesh, &plan.atlas, &png)?;
    let surface = Arc::new(Surface {
        id: state.next_id(),
        solid: solid.id,
        mesh: mesh.id.clone(),
        resolution,
        fast,
        atlas: [plan.atlas.width, plan.atlas.height],
        seconds: start.elapsed().as_secs_f64(),
        glb,
    });
    let id = surface.id;
    state.surfaces.keep(surface);
    Ok(Made::Surface {
        solid: solid.id,
        surface: id,
    })
}
