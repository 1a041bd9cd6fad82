//! The viewer page, built into the binary. Requests are answered from this fixed table only:
//! there is no file-system lookup, so no path (`..`, encoded or not) can reach a file.

pub struct Asset {
    pub content_type: &'static str,
    pub body: &'static [u8],
}

const ASSETS: &[(&str, Asset)] = &[
    (
        "/",
        Asset {
            content_type: "text/html; charset=utf-8",
            body: include_bytes!("../../assets/viewer/index.html"),
        },
    ),
    (
        "/viewer.js",
        Asset {
            content_type: "text/javascript; charset=utf-8",
            body: include_bytes!("../../assets/viewer/viewer.js"),
        },
    ),
    (
        "/viewer.css",
        Asset {
            content_type: "text/css; charset=utf-8",
            body: include_bytes!("../../assets/viewer/viewer.css"),
        },
    ),
    // The Stanford bunny as a triangle mesh for the 3D view (public domain, Stanford 3D Scanning
    // Repository; see assets/viewer/SOURCES.md): u32 vertex count V, u32 triangle count T (little
    // endian), V x 3 f32 positions in [-0.5, 0.5]^3, T x 3 u16 indices. Made by
    // assets/viewer/bunny_bin.py.
    (
        "/bunny.bin",
        Asset {
            content_type: "application/octet-stream",
            body: include_bytes!("../../assets/viewer/bunny.bin"),
        },
    ),
];

/// The asset at `path` (`/index.html` is `/`).
pub fn get(path: &str) -> Option<&'static Asset> {
    let path = if path == "/index.html" { "/" } else { path };
    ASSETS.iter().find(|(p, _)| *p == path).map(|(_, a)| a)
}

#[cfg(test)]
mod tests {
    #[test]
    fn only_table_entries_are_served() {
        assert!(super::get("/").is_some());
        assert!(super::get("/viewer.js").is_some());
        assert!(super::get("/bunny.bin").is_some());
        for p in [
            "/../Cargo.toml",
            "/%2e%2e/Cargo.toml",
            "/assets/viewer/index.html",
            "",
        ] {
            assert!(super::get(p).is_none(), "{p}");
        }
    }
}
