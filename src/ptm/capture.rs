//! Captures: N photographs of one surface under known light directions, and a synthetic
//! generator (a procedural height field with albedo, Lambertian shading and cast shadows) so tests
//! and demos need no photographs.
//!
//! Light files: the RTI `.lp` text format (first line the image count N, then one line per image:
//! `file x y z`, a direction towards the light) or JSON (`{"lights": [{"file": "a.png",
//! "direction": [x, y, z]} | {"file": "a.png", "lu": u, "lv": v}, ...]}`). Directions are
//! normalized; (lu, lv) is the projection of the unit direction onto the image plane: lu to the
//! right, lv up (towards the top row), z towards the camera.

use crate::error::{Error, Result};
use crate::util::hash::{hash32, SeededRng};
use crate::util::number_text;
use std::path::{Path, PathBuf};

/// The fewest images a biquadratic fit (6 unknowns) can use.
pub const MIN_IMAGES: usize = 6;

/// One light direction as the PTM sees it: (lu, lv), with lu^2 + lv^2 <= 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    pub lu: f64,
    pub lv: f64,
}

impl Light {
    /// From a direction towards the light (any finite length but zero, z > 0).
    pub fn from_direction(d: [f64; 3]) -> Option<Light> {
        if !(d.iter().all(|c| c.is_finite()) && d[2] > 0.0) {
            return None;
        }
        let length = |d: [f64; 3]| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        // A length whose square overflows or underflows is measured scaled to its largest
        // component; ordinary lengths keep their exact quotients.
        let d = match length(d) {
            n if n.is_finite() && n > 1e-150 => d,
            _ => d.map(|c| c / d.iter().fold(0f64, |m, c| m.max(c.abs()))),
        };
        let n = length(d);
        Some(Light {
            lu: d[0] / n,
            lv: d[1] / n,
        })
    }

    /// The unit direction towards the light.
    pub fn direction(&self) -> [f64; 3] {
        [
            self.lu,
            self.lv,
            (1.0 - self.lu * self.lu - self.lv * self.lv)
                .max(0.0)
                .sqrt(),
        ]
    }
}

/// Images of one surface (all the same size) and the light of each.
#[derive(Clone, Debug)]
pub struct Capture {
    pub images: Vec<image::RgbImage>,
    pub lights: Vec<Light>,
    /// File names (relative to the capture directory), for writing.
    pub names: Vec<String>,
}

impl Capture {
    pub fn width(&self) -> u32 {
        self.images[0].width()
    }
    pub fn height(&self) -> u32 {
        self.images[0].height()
    }

    /// Check the invariants the fit relies on; `what` names the capture for errors.
    pub fn validate(&self, what: &str) -> Result<()> {
        if self.images.len() < MIN_IMAGES {
            return Err(Error::invalid(
                what,
                format!(
                    "{} images; a PTM fit needs at least {MIN_IMAGES} (6 coefficients per pixel)",
                    self.images.len()
                ),
            ));
        }
        if self.images.len() != self.lights.len() {
            return Err(Error::invalid(
                what,
                format!(
                    "{} images but {} light directions",
                    self.images.len(),
                    self.lights.len()
                ),
            ));
        }
        if let Some(i) = self
            .lights
            .iter()
            .position(|l| !(l.lu.is_finite() && l.lv.is_finite() && l.lu.hypot(l.lv) <= 1.0 + 1e-9))
        {
            return Err(Error::invalid(
                what,
                format!("light {i}: (lu, lv) must be finite, within the unit disc"),
            ));
        }
        let (w, h) = (self.width(), self.height());
        // (Names are optional for a capture built in memory: an image is then named by its
        // place.)
        for (i, img) in self.images.iter().enumerate() {
            if img.dimensions() != (w, h) {
                let name = self.names.get(i).cloned().unwrap_or_else(|| format!("{i}"));
                return Err(Error::invalid(
                    format!("{what}: image {name}"),
                    format!(
                        "is {}x{}, the first image is {w}x{h}; all images must have one size",
                        img.width(),
                        img.height()
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// Parse a light file: (image file, light) per image, in file order.
pub fn parse_lights(text: &str, what: &str, json: bool) -> Result<Vec<(String, Light)>> {
    let bad = |p: String| Error::invalid(what, p);
    let light_of = |d: [f64; 3], i: usize| {
        Light::from_direction(d).ok_or_else(|| {
            bad(format!(
                "light {i} ({}, {}, {}) is not a finite direction above the surface (needs z > 0)",
                number_text(d[0]),
                number_text(d[1]),
                number_text(d[2])
            ))
        })
    };
    let mut out = Vec::new();
    if json {
        let v: serde_json::Value =
            serde_json::from_str(text).map_err(|e| bad(format!("not valid JSON: {e}")))?;
        let list = v
            .get("lights")
            .and_then(|l| l.as_array())
            .ok_or_else(|| bad("expected {\"lights\": [...]}".into()))?;
        for (i, e) in list.iter().enumerate() {
            let file = e
                .get("file")
                .and_then(|f| f.as_str())
                .ok_or_else(|| bad(format!("light {i} has no \"file\"")))?;
            if e.get("direction").is_some() && (e.get("lu").is_some() || e.get("lv").is_some()) {
                return Err(bad(format!(
                    "light {i} gives both \"direction\" and \"lu\"/\"lv\": give one of them"
                )));
            }
            let light = if let Some(d) = e.get("direction").and_then(|d| d.as_array()) {
                let d: Option<Vec<f64>> = d.iter().map(|x| x.as_f64()).collect();
                match d.as_deref() {
                    Some(&[x, y, z]) => light_of([x, y, z], i)?,
                    _ => {
                        return Err(bad(format!(
                            "light {i}: \"direction\" needs 3 numbers, [x, y, z]"
                        )))
                    }
                }
            } else {
                let lu = e.get("lu").and_then(|x| x.as_f64());
                let lv = e.get("lv").and_then(|x| x.as_f64());
                match (lu, lv) {
                    (Some(lu), Some(lv)) if lu * lu + lv * lv <= 1.0 => Light { lu, lv },
                    (Some(lu), Some(lv)) => {
                        return Err(bad(format!(
                            "light {i}: (lu, lv) = ({}, {}) is outside the unit disk",
                            number_text(lu),
                            number_text(lv)
                        )))
                    }
                    _ => {
                        return Err(bad(format!(
                            "light {i} needs \"direction\": [x, y, z] or \"lu\" and \"lv\""
                        )))
                    }
                }
            };
            out.push((file.to_string(), light));
        }
        return Ok(out);
    }
    // Numbered as the file's lines, comments and blank lines included.
    let mut lines = text
        .lines()
        .map(str::trim)
        .enumerate()
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let count: usize = lines
        .next()
        .and_then(|(_, l)| l.parse().ok())
        .ok_or_else(|| bad("first line must be the image count".into()))?;
    for (i, (at, line)) in lines.enumerate() {
        let parts: Vec<&str> = line.split_whitespace().collect();
        let nums: Option<Vec<f64>> = parts.iter().skip(1).map(|p| p.parse().ok()).collect();
        match (parts.len(), nums) {
            (4, Some(n)) => out.push((parts[0].to_string(), light_of([n[0], n[1], n[2]], i)?)),
            _ => {
                return Err(bad(format!(
                    "line {} {line:?}: expected `file x y z`",
                    at + 1
                )))
            }
        }
    }
    if out.len() != count {
        return Err(bad(format!(
            "announces {count} images but lists {}",
            out.len()
        )));
    }
    Ok(out)
}

/// The light file of a capture directory: `lights.lp`, `lights.json`, or the only `.lp` file.
pub fn find_light_file(dir: &Path) -> Result<PathBuf> {
    for name in ["lights.lp", "lights.json"] {
        let p = dir.join(name);
        if p.is_file() {
            return Ok(p);
        }
    }
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let lps: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "lp"))
        .collect();
    match lps.as_slice() {
        [one] => Ok(one.clone()),
        [] => Err(Error::invalid(
            format!("capture directory {}", dir.display()),
            "has no light file (lights.lp, lights.json or one *.lp)",
        )),
        _ => Err(Error::invalid(
            format!("capture directory {}", dir.display()),
            "has several .lp files; name one with --lights",
        )),
    }
}

/// Image files (by extension) directly in `dir`, sorted.
fn image_files(dir: &Path) -> Result<Vec<String>> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok())
        .filter(|e| e.path().is_file())
        .filter_map(|e| e.file_name().to_str().map(str::to_string))
        .filter(|n| {
            let l = n.to_lowercase();
            [".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp"]
                .iter()
                .any(|e| l.ends_with(e))
        })
        .collect();
    names.sort();
    Ok(names)
}

/// The files [`load`] reads for the capture in `dir`: its light file (`lights`, or found by
/// [`find_light_file`]) and its image files, so that a command can refuse to overwrite any of
/// them.
pub fn input_files(dir: &Path, lights: Option<&Path>) -> Result<Vec<PathBuf>> {
    if !dir.is_dir() {
        return Ok(Vec::new());
    }
    let mut files = vec![match lights {
        Some(p) => p.to_path_buf(),
        None => find_light_file(dir)?,
    }];
    files.extend(image_files(dir)?.into_iter().map(|name| dir.join(name)));
    Ok(files)
}

/// Load a capture directory with its light file (`lights`, or found by [`find_light_file`]).
/// The light file must list every image of the directory, each once.
pub fn load(dir: &Path, lights: Option<&Path>) -> Result<Capture> {
    if !dir.is_dir() {
        return Err(Error::invalid(
            format!("capture directory {}", dir.display()),
            "is not a directory",
        ));
    }
    let light_file = match lights {
        Some(p) => p.to_path_buf(),
        None => find_light_file(dir)?,
    };
    let what = format!("light file {}", light_file.display());
    let text = crate::io::input::read_text(&light_file)?;
    let json = light_file.extension().is_some_and(|e| e == "json");
    let entries = parse_lights(&text, &what, json)?;
    let on_disk = image_files(dir)?;
    if on_disk.len() != entries.len() {
        return Err(Error::invalid(
            &what,
            format!(
                "lists {} images but {} holds {} image files",
                entries.len(),
                dir.display(),
                on_disk.len()
            ),
        ));
    }
    let mut capture = Capture {
        images: Vec::new(),
        lights: Vec::new(),
        names: Vec::new(),
    };
    // Before any image is read.
    if entries.len() < MIN_IMAGES {
        return Err(Error::invalid(
            format!("capture {}", dir.display()),
            format!(
                "{} images; a PTM fit needs at least {MIN_IMAGES} (6 coefficients per pixel)",
                entries.len()
            ),
        ));
    }
    let mut listed = std::collections::HashSet::new();
    for (file, light) in entries {
        let path = dir.join(&file);
        if !listed.insert(file.clone()) {
            return Err(Error::invalid(
                &what,
                format!("lists {file} twice; every image of the directory is listed once"),
            ));
        }
        if !on_disk.contains(&file) {
            return Err(Error::invalid(
                &what,
                format!("lists {file}, which is not an image in {}", dir.display()),
            ));
        }
        let img = image::open(&path)
            .map_err(|e| Error::invalid(format!("image {}", path.display()), e.to_string()))?
            .to_rgb8();
        capture.images.push(img);
        capture.lights.push(light);
        capture.names.push(file);
    }
    capture.validate(&format!("capture {}", dir.display()))?;
    Ok(capture)
}

/// Write a capture: its images as PNG and `lights.lp`, into an existing empty or new directory.
/// Each file is written atomically.
pub fn save(capture: &Capture, dir: &Path) -> Result<()> {
    capture.validate("capture")?;
    // (A capture made in memory may have no names: its images are then named by their place.)
    let names: Vec<String> = (0..capture.images.len())
        .map(|i| {
            capture
                .names
                .get(i)
                .cloned()
                .unwrap_or_else(|| format!("img_{i:03}.png"))
        })
        .collect();
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let mut lp = format!("{}\n", capture.images.len());
    for ((img, light), name) in capture.images.iter().zip(&capture.lights).zip(&names) {
        let rgba = image::DynamicImage::ImageRgb8(img.clone()).to_rgba8();
        crate::io::atomic::save_png(&dir.join(name), &rgba)?;
        let d = light.direction();
        lp.push_str(&format!("{name} {:.9} {:.9} {:.9}\n", d[0], d[1], d[2]));
    }
    crate::io::atomic::write_file(&dir.join("lights.lp"), lp.as_bytes())
}

/// N light directions on a spiral: elevations spread between ~17 and ~72 degrees (several
/// elevations are needed: with one, lu^2 + lv^2 is constant and the fit is rank-deficient),
/// azimuths stepped by the golden angle.
pub fn spiral_lights(n: usize) -> Vec<Light> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let t = if n > 1 {
                i as f64 / (n - 1) as f64
            } else {
                0.5
            };
            let z = 0.3 + 0.65 * t;
            let r = (1.0 - z * z).sqrt();
            let phi = i as f64 * golden;
            Light {
                lu: r * phi.cos(),
                lv: r * phi.sin(),
            }
        })
        .collect()
}

/// The procedural surface: heights (pixels, rows top to bottom) and albedo in [0, 1].
pub struct Surface {
    pub size: u32,
    pub height: Vec<f64>,
    pub albedo: Vec<[f64; 3]>,
    /// The highest point (where shadow rays stop).
    pub max_height: f64,
}

/// Cobblestones: a periodic Voronoi pattern of domed stones with cracks between them, each stone
/// with its own colour and a little grain.
pub fn surface(size: u32, seed: u64) -> Surface {
    let n = size as usize;
    let cells = 6usize.min(n.max(1));
    let cell = size as f64 / cells as f64;
    let mut rng = SeededRng::new(seed ^ 0x5054_4d5f_4341_5054);
    let points: Vec<[f64; 2]> = (0..cells * cells)
        .map(|k| {
            let (cx, cy) = ((k % cells) as f64, (k / cells) as f64);
            let jx = 0.15 + 0.7 * (rng.below(1000) as f64 / 1000.0);
            let jy = 0.15 + 0.7 * (rng.below(1000) as f64 / 1000.0);
            [(cx + jx) * cell, (cy + jy) * cell]
        })
        .collect();
    let palette = [
        [0.72, 0.62, 0.50],
        [0.55, 0.52, 0.48],
        [0.80, 0.74, 0.62],
        [0.62, 0.48, 0.40],
        [0.48, 0.50, 0.55],
    ];
    let stone_height = cell * 0.22;
    let mut height = vec![0f64; n * n];
    let mut albedo = vec![[0f64; 3]; n * n];
    for y in 0..n {
        for x in 0..n {
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let (mut d1, mut d2, mut k1) = (f64::MAX, f64::MAX, 0usize);
            for (k, p) in points.iter().enumerate() {
                let dx = (px - p[0]).abs().min(size as f64 - (px - p[0]).abs());
                let dy = (py - p[1]).abs().min(size as f64 - (py - p[1]).abs());
                let d = (dx * dx + dy * dy).sqrt();
                if d < d1 {
                    (d2, d1, k1) = (d1, d, k);
                } else if d < d2 {
                    d2 = d;
                }
            }
            // Distance to the cell border, relative: 0 in the cracks, ~1 in stone centres.
            let edge = ((d2 - d1) / cell).clamp(0.0, 0.5) * 2.0;
            let grain = (hash32((y * n + x) as u32 ^ (seed as u32).wrapping_mul(0x9E37_79B9))
                as f64
                / u32::MAX as f64)
                - 0.5;
            height[y * n + x] = stone_height * (edge.min(0.6) / 0.6).sqrt() + 0.25 * grain;
            let base = palette[hash32(k1 as u32 ^ seed as u32) as usize % palette.len()];
            let dark = if edge < 0.12 { 0.45 } else { 1.0 };
            albedo[y * n + x] = base.map(|c| (c * dark * (1.0 + 0.15 * grain)).clamp(0.0, 1.0));
        }
    }
    let max_height = height.iter().cloned().fold(f64::MIN, f64::max);
    Surface {
        size,
        height,
        albedo,
        max_height,
    }
}

/// Fraction of direct light reaching each pixel of `s` from `light` (1 lit, 0 in a cast shadow),
/// by marching towards the light over the (periodic) height field.
fn shadow(s: &Surface, x: usize, y: usize, light: [f64; 3]) -> f64 {
    let n = s.size as usize;
    let planar = (light[0] * light[0] + light[1] * light[1]).sqrt();
    if planar < 1e-9 {
        return 1.0;
    }
    // Image rows run downwards; lv points up.
    let (dx, dy) = (light[0] / planar, -light[1] / planar);
    let rise = light[2] / planar;
    let h0 = s.height[y * n + x];
    let max_h = s.max_height;
    let mut t = 0.75;
    // Four periods at the most: a light at the horizon (rise 0) would march for ever over a
    // pixel as high as any; one that nothing has blocked by then is taken as unblocked.
    let farthest = 4.0 * n as f64;
    while h0 + t * rise <= max_h && t < farthest {
        let sx = ((x as f64 + t * dx).round() as i64).rem_euclid(n as i64) as usize;
        let sy = ((y as f64 + t * dy).round() as i64).rem_euclid(n as i64) as usize;
        if s.height[sy * n + sx] > h0 + t * rise + 0.05 {
            return 0.0;
        }
        t += 0.5;
    }
    1.0
}

/// Render `s` under `light`: albedo x (ambient + (1 - ambient) x max(0, n.l) x shadow).
pub fn render(s: &Surface, light: Light) -> image::RgbImage {
    const AMBIENT: f64 = 0.08;
    let n = s.size as usize;
    let l = light.direction();
    let h = |x: i64, y: i64| {
        s.height[(y.rem_euclid(n as i64) as usize) * n + x.rem_euclid(n as i64) as usize]
    };
    image::RgbImage::from_fn(s.size, s.size, |x, y| {
        let (xi, yi) = (x as i64, y as i64);
        let dhdx = (h(xi + 1, yi) - h(xi - 1, yi)) / 2.0;
        let dhdrow = (h(xi, yi + 1) - h(xi, yi - 1)) / 2.0;
        // y up = -row, so dh/dy = -dh/drow; normal = (-dh/dx, -dh/dy, 1).
        let nv = [-dhdx, dhdrow, 1.0];
        let len = (nv[0] * nv[0] + nv[1] * nv[1] + 1.0).sqrt();
        let ndotl = ((nv[0] * l[0] + nv[1] * l[1] + nv[2] * l[2]) / len).max(0.0);
        let lit = if ndotl > 0.0 {
            shadow(s, x as usize, y as usize, l)
        } else {
            0.0
        };
        let a = s.albedo[y as usize * n + x as usize];
        let v = a.map(|c| {
            ((c * (AMBIENT + (1.0 - AMBIENT) * ndotl * lit)) * 255.0)
                .round()
                .clamp(0.0, 255.0) as u8
        });
        image::Rgb(v)
    })
}

/// A synthetic capture: the cobblestone surface of `seed` at `size` x `size`, under `lights`
/// spiral lights.
pub fn synthetic(size: u32, lights: usize, seed: u64) -> Capture {
    let s = surface(size, seed);
    let dirs = spiral_lights(lights);
    let images = dirs.iter().map(|&l| render(&s, l)).collect();
    Capture {
        images,
        lights: dirs,
        names: (0..lights).map(|i| format!("img_{i:03}.png")).collect(),
    }
}
