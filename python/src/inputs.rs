//! Python arguments into the library's types: images and volumes from paths or NumPy arrays,
//! and the option strings the command line's flags take, refused with the flag's name.

use crate::errors::{engine_err, invalid};
use crate::ints::Int;
use numpy::prelude::*;
use numpy::{PyArrayDyn, PyUntypedArray};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyBytes, PyString};
use solidsynth::analysis::frame::InputFrame;
use solidsynth::exemplar::{load_image, Image};
use solidsynth::solid::limits;
use solidsynth::solid::FeatureMasks;
use solidsynth::synth::{CandidateMode, ColorSource, PassSchedule};
use solidsynth::{BackendChoice, Box3, Volume};
use std::path::{Path, PathBuf};

/// An image argument: a file the library decodes, or pixels already in memory.
pub enum Picture {
    File(PathBuf),
    Pixels(Image),
}

impl Picture {
    /// A path (str or os.PathLike) or a NumPy uint8 array of shape (H, W) or (H, W, C), C in
    /// 1, 3, 4; `what` names the argument in errors as the command line names it.
    pub fn from_arg(arg: &Bound<'_, PyAny>, what: &str) -> PyResult<Picture> {
        if let Ok(array) = arg.cast::<PyUntypedArray>() {
            return image_from_array(array, what).map(Picture::Pixels);
        }
        match arg.extract::<PathBuf>() {
            Ok(path) => Ok(Picture::File(path)),
            Err(_) => Err(pyo3::exceptions::PyTypeError::new_err(format!(
                "{what}: expected a path or a NumPy uint8 array, not {}",
                arg.get_type().name()?
            ))),
        }
    }

    /// The image (a file decoded, off the interpreter) and its name for messages: the
    /// command line's `exemplar PATH`, or empty for pixels (the facade then names it `what`).
    pub fn load(self, py: Python<'_>, what: &str) -> PyResult<(Image, String)> {
        match self {
            Picture::Pixels(image) => Ok((image, String::new())),
            Picture::File(path) => {
                let image = py
                    .detach(|| load_image(&path, what))
                    .map_err(crate::errors::engine_err)?;
                Ok((image, format!("{what} {}", path.display())))
            }
        }
    }

    /// The path, when this is a file ending in `.ssa` (an analysis, as the CLI's INPUT).
    pub fn analysis_path(&self) -> Option<&Path> {
        match self {
            Picture::File(p) if p.extension().is_some_and(|e| e.eq_ignore_ascii_case("ssa")) => {
                Some(p)
            }
            _ => None,
        }
    }
}

/// `ey` and `ez` come together (the command line's `--ey` requires `--ez` and back).
pub fn exemplar_pair<'a, 'py>(
    ey: Option<&'a Bound<'py, PyAny>>,
    ez: Option<&'a Bound<'py, PyAny>>,
) -> PyResult<Option<(Picture, Picture)>> {
    match (ey, ez) {
        (None, None) => Ok(None),
        (Some(y), Some(z)) => Ok(Some((
            Picture::from_arg(y, "--ey")?,
            Picture::from_arg(z, "--ez")?,
        ))),
        (Some(_), None) => Err(invalid("--ey", "needs --ez too")),
        (None, Some(_)) => Err(invalid("--ez", "needs --ey too")),
    }
}

/// The feature channel's masks as the command line reads `--feature-mask` (a keyword, or a
/// mask image) and `--ey-feature-mask`, `--ez-feature-mask` (`cli::analyze::exemplar_input`).
pub fn feature_masks(
    py: Python<'_>,
    masks: [Option<&Bound<'_, PyAny>>; 3],
    exemplars: usize,
) -> PyResult<FeatureMasks> {
    const FLAGS: [&str; 3] = ["--feature-mask", "--ey-feature-mask", "--ez-feature-mask"];
    let mut keyword = None;
    let mut given: Vec<Option<Picture>> = Vec::new();
    for (i, (arg, flag)) in masks.iter().zip(FLAGS).enumerate() {
        let Some(arg) = arg else {
            given.push(None);
            continue;
        };
        if i == 0 && arg.is_instance_of::<PyString>() {
            let text: String = arg.extract()?;
            if matches!(text.as_str(), "auto" | "edges" | "none") {
                keyword = Some(text);
                given.push(None);
                continue;
            }
        }
        given.push(Some(Picture::from_arg(arg, flag)?));
    }
    let count = given.iter().filter(|g| g.is_some()).count();
    if count == 0 {
        return Ok(match keyword.as_deref() {
            Some("edges") => FeatureMasks::Edges,
            Some("none") => FeatureMasks::None,
            _ => FeatureMasks::Auto,
        });
    }
    let exemplars = exemplars.max(1);
    if count != exemplars || given[0].is_none() {
        return Err(invalid(
            "feature masks",
            if exemplars == 3 {
                "give --feature-mask, --ey-feature-mask and --ez-feature-mask images together"
            } else {
                "give --feature-mask only (one exemplar)"
            },
        ));
    }
    let mut images = Vec::new();
    for (picture, flag) in given.into_iter().zip(FLAGS).take(exemplars) {
        let picture = picture.expect("counted above");
        images.push(picture.load(py, flag)?.0);
    }
    Ok(FeatureMasks::Images(images))
}

/// Python's spelling of a shape: `(16, 16, 3)`, `(0,)`.
fn shape_text(shape: &[usize]) -> String {
    let parts: Vec<String> = shape.iter().map(usize::to_string).collect();
    match parts.len() {
        1 => format!("({},)", parts[0]),
        _ => format!("({})", parts.join(", ")),
    }
}

/// Refuse an array that is not uint8 or is empty, naming `what`.
fn check_pixels(array: &Bound<'_, PyUntypedArray>, what: &str) -> PyResult<()> {
    let dtype = array.dtype();
    if !dtype.is_equiv_to(&numpy::dtype::<u8>(array.py())) {
        return Err(invalid(
            what,
            format!("has dtype {dtype}; expected uint8 (0..=255 per channel)"),
        ));
    }
    if array.shape().contains(&0) {
        return Err(invalid(
            what,
            format!("is empty (shape {})", shape_text(array.shape())),
        ));
    }
    Ok(())
}

/// The array's bytes in C order (x fastest, then rows, ...), whatever its strides.
fn array_bytes(array: &Bound<'_, PyUntypedArray>) -> PyResult<Vec<u8>> {
    let typed = array.cast::<PyArrayDyn<u8>>()?;
    let view = typed.try_readonly()?;
    // `as_slice` also accepts Fortran order, whose memory order is not C order.
    if typed.is_c_contiguous() {
        if let Ok(slice) = view.as_slice() {
            return Ok(slice.to_vec());
        }
    }
    Ok(view.as_array().iter().copied().collect())
}

/// An exemplar or mask from an (H, W) or (H, W, C) uint8 array.
fn image_from_array(array: &Bound<'_, PyUntypedArray>, what: &str) -> PyResult<Image> {
    let shape = array.shape().to_vec();
    let channels = match shape[..] {
        [_, _] => 1,
        [_, _, c] => c,
        _ => {
            return Err(invalid(
                what,
                format!(
                    "has shape {}; expected (H, W) or (H, W, C)",
                    shape_text(&shape)
                ),
            ))
        }
    };
    check_pixels(array, what)?;
    if !matches!(channels, 1 | 3 | 4) {
        return Err(invalid(
            what,
            format!("has {channels} channels; expected 1 (gray), 3 (RGB) or 4 (RGBA)"),
        ));
    }
    let side = |n: usize| u32::try_from(n).map_err(|_| invalid(what, "is too large"));
    Ok(Image {
        width: side(shape[1])?,
        height: side(shape[0])?,
        channels: channels as u32,
        pixels: array_bytes(array)?,
    })
}

/// A volume from a (Z, Y, X) or (Z, Y, X, C) uint8 array, C in 1..=4 (what NRRD volumes hold).
pub fn volume_from_array(array: &Bound<'_, PyUntypedArray>, what: &str) -> PyResult<Volume> {
    let shape = array.shape().to_vec();
    let channels = match shape[..] {
        [_, _, _] => 1,
        [_, _, _, c] => c,
        _ => {
            return Err(invalid(
                what,
                format!(
                    "has shape {}; expected (Z, Y, X) or (Z, Y, X, C)",
                    shape_text(&shape)
                ),
            ))
        }
    };
    check_pixels(array, what)?;
    if !(1..=4).contains(&channels) {
        return Err(invalid(
            what,
            format!("has {channels} channels; expected 1 to 4"),
        ));
    }
    let side = |n: usize| u32::try_from(n).map_err(|_| invalid(what, "is too large"));
    Ok(Volume {
        nx: side(shape[2])?,
        ny: side(shape[1])?,
        nz: side(shape[0])?,
        channels: channels as u32,
        data: array_bytes(array)?,
    })
}

/// `--backend`, parsed by the library.
pub fn backend_choice(name: &str) -> PyResult<BackendChoice> {
    name.parse()
        .map_err(|problem: String| invalid(format!("--backend {name}"), problem))
}

/// `--candidates`, parsed by the library.
pub fn candidate_mode(name: &str) -> PyResult<CandidateMode> {
    name.parse()
        .map_err(|problem: String| invalid(format!("--candidates {name}"), problem))
}

/// `--frame` (None: the default the library resolves), parsed by the library.
pub fn input_frame(name: Option<&str>) -> PyResult<Option<InputFrame>> {
    name.map(|text| {
        text.parse()
            .map_err(|problem: String| invalid(format!("--frame {text}"), problem))
    })
    .transpose()
}

/// `--color`, parsed by the library.
pub fn color_source(text: &str) -> PyResult<ColorSource> {
    text.parse::<ColorSource>()
        .map_err(|problem| invalid(format!("--color {text}"), problem))
}

/// `passes=`: a count for every level, `"2,2,2,1"`, or a sequence of counts (coarsest first),
/// held as `--passes` spells it so that the library's parser checks and names it.
pub struct PassesArg(String);

impl PassesArg {
    pub fn count(n: u32) -> PassesArg {
        PassesArg(n.to_string())
    }

    pub fn schedule(&self) -> PyResult<PassSchedule> {
        self.0
            .parse::<PassSchedule>()
            .map_err(|problem| invalid(format!("--passes {}", self.0), problem))
    }
}

/// An int that is not a bool, as its decimal text.
fn int_text(obj: &Bound<'_, PyAny>) -> Option<String> {
    if obj.is_instance_of::<PyBool>() {
        return None;
    }
    Some(crate::ints::index(obj)?.str().ok()?.to_string())
}

impl<'a, 'py> FromPyObject<'a, 'py> for PassesArg {
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<PassesArg> {
        if let Ok(text) = obj.cast::<PyString>() {
            return Ok(PassesArg(text.to_string()));
        }
        if let Some(text) = int_text(&obj) {
            return Ok(PassesArg(text));
        }
        // Any iterable of ints (a list, a tuple, a NumPy array), but not bytes.
        let counts = (!obj.is_instance_of::<PyBytes>())
            .then(|| obj.try_iter().ok())
            .flatten()
            .and_then(|items| {
                items
                    .map(|item| int_text(&item.ok()?))
                    .collect::<Option<Vec<String>>>()
            });
        match counts {
            Some(counts) => Ok(PassesArg(counts.join(","))),
            None => Err(PyTypeError::new_err(format!(
                "passes: expected an int, a string such as \"2,2,2,1\" or a sequence of ints, \
                 got {}",
                obj.get_type().name()?
            ))),
        }
    }
}

/// `cache=`: the user's analysis cache (True, the command line's), none (False), or a directory.
pub enum CacheArg {
    Flag(bool),
    Dir(PathBuf),
}

impl<'a, 'py> FromPyObject<'a, 'py> for CacheArg {
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<CacheArg> {
        // (`bool` extraction takes Python's and NumPy's booleans, not ints.)
        if let Ok(flag) = obj.extract::<bool>() {
            return Ok(CacheArg::Flag(flag));
        }
        let is_path =
            obj.is_instance_of::<PyString>() || obj.hasattr("__fspath__").unwrap_or(false);
        if !is_path {
            return Err(PyTypeError::new_err(format!(
                "cache: expected True, False or a directory (str or os.PathLike), got {}",
                obj.get_type().name()?
            )));
        }
        let dir: PathBuf = obj.extract()?;
        if dir.as_os_str().is_empty() {
            return Err(invalid(
                "cache ''",
                "is an empty path; give a directory, True (the user's cache) or False (none)",
            ));
        }
        Ok(CacheArg::Dir(dir))
    }
}

/// `(lo, hi)` as the command line checks `--box X0,Y0,Z0,X1,Y1,Z1`, with its messages.
pub fn checked_box(lo: [Int; 3], hi: [Int; 3]) -> PyResult<Box3> {
    let all = [&lo[..], &hi[..]].concat();
    let what = format!(
        "--box {}",
        all.iter().map(Int::text).collect::<Vec<_>>().join(",")
    );
    let (Some(lo), Some(hi)) = (to_i64(&lo), to_i64(&hi)) else {
        return Err(invalid(
            what,
            format!("coordinates must lie within +-{}", limits::COORDINATE_LIMIT),
        ));
    };
    limits::checked_box(&what, lo, hi, limits::MAX_BOX_SIDE as i64).map_err(engine_err)
}

fn to_i64(corner: &[Int; 3]) -> Option<[i64; 3]> {
    Some([corner[0].get()?, corner[1].get()?, corner[2].get()?])
}
