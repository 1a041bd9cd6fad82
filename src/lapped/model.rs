//! The LST model (a lapped solid textured model) and its file format (`.lst`).
//!
//! In memory and on disk: the tet mesh, the exemplar and masks it was filled with, and per tet
//! the list of its layers in paste order, each the patch id, the mask index and the 3D texture
//! coordinates of the tet's four vertices (paper 5.1: "a list of 3D texture coordinates
//! assigned to each of its four vertices").
//!
//! Colour at a point of tet t with barycentric coordinates b: for each layer in order, w = sum
//! b_k w_k, alpha = mask(w), colour = exemplar(w), composited "over" the previous ones; the
//! result is divided by the accumulated alpha (the coverage test guarantees it reaches 1 at the
//! sample points; between them the division removes the faint seams of partial sums).
//!
//! File layout (little-endian), every count checked against the bytes left before anything is
//! allocated, a CRC-32 at the end:
//! ```text
//! "SSLST001"                     magic and version
//! u32 n, n bytes                 JSON header: texture_type, seed, exemplar_source,
//!                                exemplar_size, mask_size, masks, vertices, tets, patches
//! exemplar_size^3 x RGBA8        the exemplar, x fastest
//! masks x mask_size^3 u8         the alpha masks
//! vertices x 3 f32               positions
//! tets x 4 u32                   vertex ids, positively oriented
//! per tet: u32 count, count x (u32 patch, u8 mask, 12 f32 texture coordinates)
//! u32                            CRC-32 of everything before it
//! ```

use super::exemplar::{Mask, SolidExemplar};
use super::field::TextureType;
use super::paste::Patch;
use super::tetmesh::TetMesh;
use crate::error::{Error, Result};
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::path::Path;

const MAGIC: &[u8; 8] = b"SSLST001";
/// Coverage past which further (lower) layers cannot change an 8-bit colour by half a level.
pub const OPAQUE: f32 = 1.0 - 1.0 / 512.0;
const MAX_HEADER: usize = 1 << 16;

/// One layer of a tet: a patch's texture coordinates at the tet's vertices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Layer {
    pub patch: u32,
    pub mask: u8,
    pub coords: [[f32; 3]; 4],
}

#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Header {
    pub texture_type: String,
    pub seed: u64,
    pub exemplar_source: String,
    pub exemplar_size: u32,
    pub mask_size: u32,
    pub masks: u32,
    pub vertices: u32,
    pub tets: u32,
    pub patches: u32,
}

#[derive(Clone, Debug, PartialEq)]
pub struct LstModel {
    pub kind: TextureType,
    pub seed: u64,
    pub exemplar_source: String,
    pub exemplar: SolidExemplar,
    pub masks: Vec<Mask>,
    pub mesh: TetMesh,
    pub patches: u32,
    pub layers: Vec<Vec<Layer>>,
}

impl LstModel {
    /// Assemble a model from the pasted patches (per-tet lists in paste order).
    pub fn from_patches(
        kind: TextureType,
        seed: u64,
        exemplar_source: String,
        exemplar: SolidExemplar,
        masks: Vec<Mask>,
        mesh: TetMesh,
        patches: &[Patch],
    ) -> LstModel {
        let mut layers = vec![Vec::new(); mesh.tets.len()];
        for (id, p) in patches.iter().enumerate() {
            for &t in &p.tets {
                let coords = mesh.tets[t as usize].map(|v| p.coords[&v].as_vec3().to_array());
                layers[t as usize].push(Layer {
                    patch: id as u32,
                    mask: p.mask,
                    coords,
                });
            }
        }
        // Positions as the file stores them (f32), so a model shades the same before and
        // after a save and load.
        let mesh = TetMesh {
            vertices: mesh
                .vertices
                .iter()
                .map(|v| v.as_vec3().as_dvec3())
                .collect(),
            tets: mesh.tets,
        };
        LstModel {
            kind,
            seed,
            exemplar_source,
            exemplar,
            masks,
            mesh,
            patches: patches.len() as u32,
            layers,
        }
    }

    /// Mean number of layers per tet.
    pub fn mean_layers(&self) -> f64 {
        self.layers.iter().map(Vec::len).sum::<usize>() as f64 / self.layers.len().max(1) as f64
    }

    /// Composited RGBA (0..255) at barycentric `b` of tet `t`; alpha is the accumulated mask
    /// coverage (255 where fully covered).
    ///
    /// Layers composite "over" in paste order; evaluated front to back (last pasted first),
    /// which gives the same result and lets the loop stop once the coverage is opaque to 8 bits
    /// ([`OPAQUE`]): the layers below then contribute less than half a level.
    pub fn shade(&self, t: usize, b: [f32; 4]) -> [f32; 4] {
        let depth_varying = self.kind.depth_varying();
        let (mut color, mut cover) = ([0.0f32; 3], 0.0f32);
        for layer in self.layers[t].iter().rev() {
            let c = &layer.coords;
            let mut w = [0.0f32; 3];
            for k in 0..4 {
                for a in 0..3 {
                    w[a] += b[k] * c[k][a];
                }
            }
            let alpha = self.masks[layer.mask as usize].sample_f32(w);
            if alpha <= 0.0 {
                continue;
            }
            let e = self.exemplar.sample_rgb(w, depth_varying);
            let weight = (1.0 - cover) * alpha;
            for a in 0..3 {
                color[a] += weight * e[a];
            }
            cover += weight;
            if cover >= OPAQUE {
                break;
            }
        }
        if cover <= 0.0 {
            return [0.0; 4];
        }
        [
            color[0] / cover,
            color[1] / cover,
            color[2] / cover,
            cover * 255.0,
        ]
    }

    pub fn header(&self) -> Header {
        Header {
            texture_type: self.kind.name().to_string(),
            seed: self.seed,
            exemplar_source: self.exemplar_source.clone(),
            exemplar_size: self.exemplar.size,
            mask_size: self.masks[0].size,
            masks: self.masks.len() as u32,
            vertices: self.mesh.vertices.len() as u32,
            tets: self.mesh.tets.len() as u32,
            patches: self.patches,
        }
    }

    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        out.extend_from_slice(MAGIC);
        let header = serde_json::to_vec(&self.header()).expect("header serializes");
        out.extend_from_slice(&(header.len() as u32).to_le_bytes());
        out.extend_from_slice(&header);
        out.extend_from_slice(&self.exemplar.rgba);
        for m in &self.masks {
            out.extend_from_slice(&m.alpha);
        }
        for v in &self.mesh.vertices {
            for c in v.as_vec3().to_array() {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
        for t in &self.mesh.tets {
            for i in t {
                out.extend_from_slice(&i.to_le_bytes());
            }
        }
        for list in &self.layers {
            out.extend_from_slice(&(list.len() as u32).to_le_bytes());
            for l in list {
                out.extend_from_slice(&l.patch.to_le_bytes());
                out.push(l.mask);
                for c in l.coords.iter().flatten() {
                    out.extend_from_slice(&c.to_le_bytes());
                }
            }
        }
        let crc = crc32fast::hash(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        out
    }

    pub fn save(&self, path: &Path) -> Result<()> {
        crate::io::atomic::write_file(path, &self.to_bytes())
    }

    pub fn load(path: &Path) -> Result<LstModel> {
        let bytes = crate::io::input::read(path)?;
        Self::parse(&bytes).map_err(|problem| Error::corrupt(path, problem))
    }

    /// Parse an `.lst` file; the error says what is wrong.
    pub fn parse(bytes: &[u8]) -> std::result::Result<LstModel, String> {
        if bytes.len() < MAGIC.len() + 8 || &bytes[..8] != MAGIC {
            return Err("not a solidsynth LST model (bad magic)".into());
        }
        let (body, crc) = bytes.split_at(bytes.len() - 4);
        if crc32fast::hash(body) != u32::from_le_bytes(crc.try_into().unwrap()) {
            return Err("checksum mismatch: the file is damaged or truncated".into());
        }
        let mut r = Reader { bytes: body, at: 8 };
        let header_len = r.u32()? as usize;
        if header_len > MAX_HEADER {
            return Err(format!("header of {header_len} bytes is too large"));
        }
        let header: Header =
            serde_json::from_slice(r.take(header_len)?).map_err(|e| format!("bad header: {e}"))?;
        let kind = TextureType::parse(&header.texture_type)
            .ok_or_else(|| format!("unknown texture type {:?}", header.texture_type))?;
        let expected_masks = if kind.depth_varying() { 3 } else { 1 };
        if header.masks != expected_masks {
            return Err(format!(
                "{} masks for texture type {}, expected {expected_masks}",
                header.masks, header.texture_type
            ));
        }
        let e = header.exemplar_size as usize;
        if !(2..=super::exemplar::MAX_EXEMPLAR as usize).contains(&e) {
            return Err(format!("exemplar size {e} out of range"));
        }
        let m = header.mask_size as usize;
        if !(2..=256).contains(&m) {
            return Err(format!("mask size {m} out of range"));
        }
        let rgba = r.take(e * e * e * 4)?.to_vec();
        let masks = (0..header.masks)
            .map(|_| {
                Ok(Mask {
                    size: m as u32,
                    alpha: r.take(m * m * m)?.to_vec(),
                })
            })
            .collect::<std::result::Result<Vec<_>, String>>()?;
        let nv = header.vertices as usize;
        let nt = header.tets as usize;
        r.need(nv.saturating_mul(12))?;
        let mut vertices = Vec::with_capacity(nv);
        for _ in 0..nv {
            let p = [r.f32()?, r.f32()?, r.f32()?];
            if p.iter().any(|c| !c.is_finite()) {
                return Err("a vertex has a non-finite coordinate".into());
            }
            vertices.push(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64));
        }
        r.need(nt.saturating_mul(16))?;
        let mut tets = Vec::with_capacity(nt);
        for i in 0..nt {
            let t = [r.u32()?, r.u32()?, r.u32()?, r.u32()?];
            if t.iter().any(|&i| i as usize >= nv) {
                return Err("a tet refers to a vertex beyond those defined".into());
            }
            // The fill writes positively oriented tets, and cuts and bakes rely on it.
            if TetMesh::signed_volume6(&t.map(|v| vertices[v as usize])) <= 0.0 {
                return Err(format!(
                    "tet {i} is flat or inverted (its corners are not positively oriented)"
                ));
            }
            tets.push(t);
        }
        let mut layers = Vec::with_capacity(nt);
        for _ in 0..nt {
            let count = r.u32()? as usize;
            r.need(count.saturating_mul(53))?;
            let mut list = Vec::with_capacity(count);
            for _ in 0..count {
                let patch = r.u32()?;
                let mask = r.take(1)?[0];
                if patch >= header.patches || mask as u32 >= header.masks {
                    return Err("a layer refers to a patch or mask beyond those defined".into());
                }
                let mut coords = [[0.0f32; 3]; 4];
                for c in coords.iter_mut().flatten() {
                    *c = r.f32()?;
                    if !c.is_finite() {
                        return Err("a texture coordinate is not finite".into());
                    }
                }
                list.push(Layer {
                    patch,
                    mask,
                    coords,
                });
            }
            layers.push(list);
        }
        if r.at != body.len() {
            return Err(format!("{} unexpected bytes at the end", body.len() - r.at));
        }
        Ok(LstModel {
            kind,
            seed: header.seed,
            exemplar_source: header.exemplar_source,
            exemplar: SolidExemplar {
                size: e as u32,
                rgba,
            },
            masks,
            mesh: TetMesh { vertices, tets },
            patches: header.patches,
            layers,
        })
    }
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn need(&self, n: usize) -> std::result::Result<(), String> {
        if self.bytes.len() - self.at < n {
            Err("truncated: the counts in the file exceed its size".into())
        } else {
            Ok(())
        }
    }
    fn take(&mut self, n: usize) -> std::result::Result<&'a [u8], String> {
        self.need(n)?;
        let s = &self.bytes[self.at..self.at + n];
        self.at += n;
        Ok(s)
    }
    fn u32(&mut self) -> std::result::Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().unwrap()))
    }
    fn f32(&mut self) -> std::result::Result<f32, String> {
        Ok(f32::from_le_bytes(self.take(4)?.try_into().unwrap()))
    }
}
