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
        "/cuts.js",
        Asset {
            content_type: "text/javascript; charset=utf-8",
            body: include_bytes!("../../assets/viewer/cuts.js"),
        },
    ),
    (
        "/view3d.js",
        Asset {
            content_type: "text/javascript; charset=utf-8",
            body: include_bytes!("../../assets/viewer/view3d.js"),
        },
    ),
    (
        "/meshes.js",
        Asset {
            content_type: "text/javascript; charset=utf-8",
            body: include_bytes!("../../assets/viewer/meshes.js"),
        },
    ),
    (
        "/viewer.css",
        Asset {
            content_type: "text/css; charset=utf-8",
            body: include_bytes!("../../assets/viewer/viewer.css"),
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
        assert!(super::get("/cuts.js").is_some());
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
