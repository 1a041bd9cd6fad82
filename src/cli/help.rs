//! Text at the end of `--help`: the tool's exit codes and environment, and each command's
//! examples. Every example runs as written in an empty directory holding the repository's
//! `assets/` and `examples/` (tests/docs_commands.rs runs them all), at sizes that take seconds.

/// After `solidsynth --help`.
pub const TOOL: &str = "\
Exit codes:
  0    success
  1    internal failure (a bug or a device error)
  2    bad input: the message names the input or flag and the problem; nothing is written
  130  interrupted (Ctrl-C): outputs in progress are removed

Environment:
  SOLIDSYNTH_LOG               log filter (tracing syntax), e.g. debug or solidsynth=debug
  SOLIDSYNTH_ADAPTER           use the GPU adapter whose name contains this (as --adapter)
  SOLIDSYNTH_CACHE_DIR         analysis cache (default $XDG_CACHE_HOME/solidsynth, else
                               ~/.cache/solidsynth)
  SOLIDSYNTH_GPU_TIMEOUT_S     seconds to wait for one GPU submission before failing
  SOLIDSYNTH_MEMORY_BUDGET_MIB memory the estimates may plan for (default: what the
                               machine or its cgroup has available)
  SOLIDSYNTH_SHADER_DIR        read the WGSL kernels from this directory (development)
  NO_COLOR                     no ANSI colour in log lines (colour is used on terminals only)
  LP_NATIVE_VECTOR_WIDTH       lavapipe's vector width (unless given, on AVX-512 hosts: 512,
                               or 256 for `lapped render`)

Examples:
  solidsynth synth --size 64 -o solid.nrrd --sheet sheet.png
  solidsynth cut --origin 0,0,32 --normal 1,1,2 --size 256 -o cut.png
  solidsynth serve

Reference: docs/cli.md; formats: docs/formats.md.";

pub const ANALYZE: &str = "\
Examples:
  solidsynth analyze -o builtin.ssa
  solidsynth analyze assets/default-exemplar.png --feature-mask edges -o edges.ssa";

pub const EVAL: &str = "\
Examples:
  solidsynth synth --size 32 -o solid.nrrd
  solidsynth eval assets/default-exemplar.png solid.nrrd --sheet sheet.png";

pub const SYNTH: &str = "\
Examples:
  solidsynth synth --size 64 -o solid.nrrd --sheet sheet.png
  solidsynth synth --size 32 --tileable --seed 2 -o tile.nrrd --flipbook tile.png
  solidsynth synth --size 32 --color matched --jitter 0.5 -o matched.nrrd --slices slices";

pub const REGION: &str = "\
Examples:
  solidsynth region --box=-16,-16,100,16,16,132 -o block.nrrd
  solidsynth region --box 0,0,0,64,64,8 --seed 3 -o slab.tif --vti slab.vti";

pub const CUT: &str = "\
Examples:
  solidsynth cut --origin 0,0,32 --normal 0,0,1 --size 128 -o z.png
  solidsynth cut --origin 100,-40,7 --normal 1,2,3 --size 128 --spacing 0.5 -o oblique.png
  solidsynth cut --origin 0,0,0 --normal 1,1,1 --size 64 --coarse-cache 64 --repeat 3 -o warm.png";

pub const SURFACE: &str = "\
Examples:
  solidsynth surface --mesh examples/octahedron.obj --resolution 48 --texels 5 -o octahedron.glb
  solidsynth surface --mesh examples/octahedron.obj --resolution 48 -o octahedron.obj
  solidsynth surface --mesh examples/uv-cube.obj --uv own --resolution 48 -o cube.glb";

pub const INSPECT: &str = "\
Examples:
  solidsynth analyze -o builtin.ssa
  solidsynth inspect builtin.ssa --slab slab.png";

pub const SERVE: &str = "\
Examples:
  solidsynth serve
  solidsynth serve assets/default-exemplar.png --port 8080 --allow-host myhost.local";

pub const ADAPTERS: &str = "\
Examples:
  solidsynth adapters
  solidsynth adapters --json";

pub const COMPLETIONS: &str = "\
Examples:
  solidsynth completions bash > solidsynth.bash
  solidsynth completions zsh > _solidsynth";

pub const MAN: &str = "\
Examples:
  solidsynth man -o man";

pub const GRADIENT_SYNTH: &str = "\
Examples:
  solidsynth gradient synth --size 16 --iterations 1 --backend cpu -o gradient.gsolid";

pub const GRADIENT_VECTORIZE: &str = "\
Examples:
  solidsynth synth --size 32 --tileable -o tile.nrrd
  solidsynth gradient vectorize tile.nrrd -o tile.gsolid";

pub const GRADIENT_RENDER: &str = "\
Examples:
  solidsynth gradient synth --size 16 --iterations 1 --backend cpu -o gradient.gsolid
  solidsynth gradient render gradient.gsolid --size 32 -o gradient.nrrd
  solidsynth gradient render gradient.gsolid --normal 1,1,1 --size 128 -o gradient-cut.png";

pub const GRADIENT_EDIT: &str = "\
Examples:
  solidsynth gradient synth --size 16 --iterations 1 --backend cpu -o gradient.gsolid
  solidsynth gradient edit gradient.gsolid --strokes examples/gradient/strokes.json --color 200,40,40 -o edited.gsolid";

pub const PTM_CAPTURE: &str = "\
Examples:
  solidsynth ptm capture --size 64 --lights 12 -o capture";

pub const PTM_FIT: &str = "\
Examples:
  solidsynth ptm capture --size 64 --lights 12 -o capture
  solidsynth ptm fit capture -o surface.ptm";

pub const PTM_SYNTH: &str = "\
Examples:
  solidsynth ptm capture --size 64 --lights 12 -o capture
  solidsynth ptm fit capture -o surface.ptm
  solidsynth ptm synth surface.ptm --size 96 -o larger.ptm";

pub const PTM_RELIGHT: &str = "\
Examples:
  solidsynth ptm capture --size 64 --lights 12 -o capture
  solidsynth ptm fit capture -o surface.ptm
  solidsynth ptm relight surface.ptm --light 0.5,0.3 -o lit.png
  solidsynth ptm relight surface.ptm --sweep 8 -o ring.png";

pub const LAPPED_FILL: &str = "\
Examples:
  solidsynth synth --size 32 --tileable -o tile.nrrd
  solidsynth lapped fill --mesh builtin:sphere --exemplar tile.nrrd --resolution 6 -o sphere.lst";

pub const LAPPED_CUT: &str = "\
Examples:
  solidsynth synth --size 32 --tileable -o tile.nrrd
  solidsynth lapped fill --mesh builtin:sphere --exemplar tile.nrrd --resolution 6 -o sphere.lst
  solidsynth lapped cut sphere.lst --origin center --normal 0,0.3,1 --size 128 -o sphere-cut.png";

pub const LAPPED_RENDER: &str = "\
Examples:
  solidsynth synth --size 32 --tileable -o tile.nrrd
  solidsynth lapped fill --mesh builtin:sphere --exemplar tile.nrrd --resolution 6 -o sphere.lst
  solidsynth lapped render sphere.lst --camera 30,20 --size 128 -o sphere-view.png";

pub const LAPPED_BAKE: &str = "\
Examples:
  solidsynth synth --size 32 --tileable -o tile.nrrd
  solidsynth lapped fill --mesh builtin:sphere --exemplar tile.nrrd --resolution 6 -o sphere.lst
  solidsynth lapped bake sphere.lst -o sphere.glb";

pub const LAPPED_EXEMPLAR: &str = "\
Examples:
  solidsynth lapped exemplar --kind kiwi --size 32 -o kiwi.nrrd
  solidsynth lapped fill --mesh builtin:sphere --exemplar kiwi.nrrd --field examples/lapped/kiwi.json --resolution 6 -o kiwi.lst";

pub const BENCH_ANALYZE: &str = "\
Examples:
  solidsynth bench analyze --sizes 32,64";

pub const BENCH_SYNTH: &str = "\
Examples:
  solidsynth bench synth --sizes 32 --backends cpu --runs 1";

pub const BENCH_GRADIENT_SYNTH: &str = "\
Examples:
  solidsynth bench gradient-synth --sizes 16 --backends cpu --runs 1";

pub const BENCH_GRADIENT_RENDER: &str = "\
Examples:
  solidsynth bench gradient-render --sizes 32 --runs 1 --no-gpu";

pub const BENCH_PTM: &str = "\
Examples:
  solidsynth bench ptm --size 96 --runs 1 --no-gpu";

pub const BENCH_LAPPED: &str = "\
Examples:
  solidsynth bench lapped --resolution 6 --runs 1 --cuts 3";

pub const BENCH_COMPARE: &str = "\
Examples:
  solidsynth bench compare --quick --runs 1 --adapters none
  solidsynth bench compare --quick --runs 1 --adapters none --json";

pub const BENCH_SERVE: &str = "\
Examples:
  solidsynth bench serve --clients 2 --requests 8 --size 64 --backend cpu";
