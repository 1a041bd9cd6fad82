//! The kernel contract: the data both backends read, below everything else of the engine. The
//! uniform structs of the WGSL kernels ([`uniforms`]), a level's packed exemplar data
//! ([`level`]), the brick ABI of synthesis states ([`bricks`]), the jitter field's tables
//! ([`jitter`]), exemplar coordinates and triples ([`triple`]), and the small input and output
//! types the CPU references and the GPU dispatches share (a PCA basis, a gradient solid and its
//! query points, a PTM and its light, a lapped model's render scene, bucket sums). It imports
//! nothing from the domains (`lazy`, `gradient`, `ptm`, `lapped`, `analysis`); `cpu/` and `gpu/`
//! import only this layer besides the base (`util`, `error`, `exemplar`'s image type).

pub mod bricks;
pub mod buckets;
pub mod jitter;
pub mod lapped;
pub mod level;
pub mod pca;
pub mod ptm;
pub mod tricubic;
pub mod triple;
pub mod uniforms;
