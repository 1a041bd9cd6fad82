//! The synthesis engine: kernel semantics on constructed states, spatial determinism, colours,
//! tileable solids; a module each.

mod colours;
#[path = "../common/mod.rs"]
mod common;
mod correction;
mod determinism;
mod tileable;

use solidsynth::analysis::frame::{pack, unpack};
use solidsynth::exemplar::Border;
use solidsynth::lazy::pack::LevelPack;
use solidsynth::lazy::{bricks, Box3, CandidateMode};
