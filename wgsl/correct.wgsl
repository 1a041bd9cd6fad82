// One correction sub-pass over the voxels of one parity class in a box (paper 5.1, two-step
// search with 3D candidates; or independent 2D candidates, mode 1). CPU reference, with the
// description of each step: src/cpu/correct/mod.rs.

struct CorrectParams {
    ex: ExemplarFields,
    grid_lo_x: i32, grid_lo_y: i32, grid_lo_z: i32,
    grid_x: u32, grid_y: u32, grid_z: u32,
    table_offset: u32,
    list_offset: u32, list_count: u32,
    class_x: u32, class_y: u32, class_z: u32,
    pca_in: u32, pca_out: u32, shift: u32, proj_words: u32,
    k2d: u32, k3d_used: u32, k3d_stride: u32,
    mode: u32,
    shared_sets: u32,
    proj0: u32, proj1: u32, proj2: u32,
    mean0: u32, mean1: u32, mean2: u32,
    weights0: u32, weights1: u32, weights2: u32,
    cand2d0: u32, cand2d1: u32, cand2d2: u32,
    cand3d0: u32, cand3d1: u32, cand3d2: u32,
    counts0: u32, counts1: u32, counts2: u32,
    grid_stride: u32, mask_offset: u32, period: u32,
    _r0: u32, _r1: u32,
}

// Pipeline-overridable copies of params.ex.channels, params.pca_out and params.k2d (the host sets
// them equal): constant loop bounds let the driver unroll the hot loops and keep the
// accumulators in registers. The kernel checks they agree with the uniforms.
override CHANNELS: u32 = 3u;
override PCA_OUT: u32 = 8u;
override K2D: u32 = 2u;
// How the projection weights are laid out (see `ProjectionWeights`): PLAIN, HALVES or BYTES.
override WEIGHT_LAYOUT: u32 = 0u;
const PLAIN: u32 = 0u;
const HALVES: u32 = 1u;
const BYTES: u32 = 2u;
// Listed bricks per block of the k-major thread layout (`class_voxel`): 16 on a CPU device with
// 16-lane subgroups (lavapipe at 512 bits, whose lanes' neighbour lookups then agree), else 8
// (`block_bricks` in src/gpu/synth.rs; `SOLIDSYNTH_BLOCK_BRICKS` overrides it).
override BLOCK_BRICKS: u32 = 8u;

@group(0) @binding(0) var<uniform> params: CorrectParams;
// (binding 1: level data, declared by the prelude)
// The state, corrected in place: a sub-pass writes its voxels' new values straight into it (see
// `neighbour_word` for why none of its reads sees one of its writes).
@group(0) @binding(3) var<storage, read_write> state: array<u32>;
// (binding 4: the level's brick index, declared by the prelude)
// The level's candidate tables (src/gpu/candidate_tables.rs): each 2D and 3D candidate with its
// scale and projections in one run of words, so scoring it reads one place. Header: plane a's
// 2D table at word a, set s's 3D table at word 3 + s, 3D slots per pixel at word 6. Entries are
// padded to whole vec4s (entry_2d, entry_3d there).
@group(0) @binding(6) var<storage, read> tables: array<u32>;
// The state as the pass began: a voxel reads its neighbours outside its own brick here, those
// inside as the pass's earlier sub-passes left them (brick-local sub-passes,
// src/cpu/correct/mod.rs), so a pass depends on its bricks and 2 voxels around them only
// (src/lazy/plan.rs).
@group(0) @binding(7) var<storage, read> pass_start: array<u32>;

// Index of voxel p in the state (ABSENT when its brick is not stored).
fn state_index(pos: vec3<i32>) -> u32 {
    return voxel_index_wrapped(pos, vec3<i32>(params.grid_lo_x, params.grid_lo_y, params.grid_lo_z),
        vec3<u32>(params.grid_x, params.grid_y, params.grid_z), params.table_offset, params.period);
}

fn stride() -> u32 {
    return 3u + params.ex.pixel_words;
}

// The stored bricks that a voxel's three 5x5 plane neighbourhoods reach. Along each axis a
// window of +-2 around local coordinate l (0..3) stays within l's brick and the neighbour brick
// on l's nearer side, so the seven bricks here (own, one step along x, y, z, and the diagonal
// steps within each plane) cover all 75 neighbours: seven brick-table reads per voxel instead of
// one per neighbour. Each holds its slot's first voxel index (slot * 64) or ABSENT. Periodic
// states wrap whole bricks (periods are multiples of 4), so local coordinates survive the wrap.
struct Around {
    local: vec3<i32>,
    own: u32,
    x: u32, y: u32, z: u32,
    yz: u32, zx: u32, xy: u32,
}

fn brick_base(p: vec3<i32>) -> u32 {
    let s = state_index(p);
    return select(s & ~63u, ABSENT, s == ABSENT);
}

fn around(pos: vec3<i32>) -> Around {
    let local = pos & vec3<i32>(3);
    // Two voxels toward the nearer neighbour brick along each axis.
    let step = select(vec3<i32>(2), vec3<i32>(-2), local < vec3<i32>(2));
    let sx = vec3<i32>(step.x, 0, 0);
    let sy = vec3<i32>(0, step.y, 0);
    let sz = vec3<i32>(0, 0, step.z);
    return Around(local, brick_base(pos), brick_base(pos + sx), brick_base(pos + sy),
        brick_base(pos + sz), brick_base(pos + sy + sz), brick_base(pos + sz + sx),
        brick_base(pos + sx + sy));
}

// State index of the voxel at (du, dv) (|du|, |dv| <= 2) in plane a of the voxel `r` surrounds
// (u = axis (a + 1) % 3, v = axis (a + 2) % 3); ABSENT when its brick is not stored.
fn plane_neighbour(r: Around, a: u32, du: i32, dv: i32) -> u32 {
    let ua = (a + 1u) % 3u;
    let va = (a + 2u) % 3u;
    let nu = r.local[ua] + du;
    let nv = r.local[va] + dv;
    let cross_u = nu < 0 || nu > 3;
    let cross_v = nv < 0 || nv > 3;
    // This plane's bricks: own, along u, along v, along both.
    let along_u = select(select(r.x, r.z, a == 1u), r.y, a == 0u);
    let along_v = select(select(r.y, r.x, a == 1u), r.z, a == 0u);
    let along_uv = select(select(r.xy, r.zx, a == 1u), r.yz, a == 0u);
    let base = select(select(r.own, along_u, cross_u), select(along_v, along_uv, cross_u), cross_v);
    var n = r.local;
    n[ua] = nu & 3;
    n[va] = nv & 3;
    return select(base + u32(n.z * 16 + n.y * 4 + n.x), ABSENT, base == ABSENT);
}

// Whether the voxel at (du, dv) in plane a of the voxel `r` surrounds lies in its brick. Only
// positions decide it, so the lanes of a SIMD group (one class voxel k of BLOCK_BRICKS bricks) agree,
// and the branch in `neighbour_word` reads one buffer.
fn in_own_brick(r: Around, a: u32, du: i32, dv: i32) -> bool {
    let nu = r.local[(a + 1u) % 3u] + du;
    let nv = r.local[(a + 2u) % 3u] + dv;
    return nu >= 0 && nu <= 3 && nv >= 0 && nv <= 3;
}

// Word w of the stored voxel s (not ABSENT) as the sub-pass sees it: in the own brick as the
// pass's earlier sub-passes left it, elsewhere as the pass began. `same_class`: s is of the
// sub-pass's class (its offset from the corrected voxel is even along every axis). A pass
// corrects each class once (`GpuSynth::correct_pass` checks it), so such a voxel still holds
// its pass-start value and is read from the pass-start copy; a sub-pass writes only voxels of
// its class, so none of its reads of `state` sees one of its writes, and its results go
// straight into the state: no records, no second dispatch to write them back, whose stores
// lavapipe makes lane by lane (the same bytes with one dispatch per sub-pass instead of two, in
// the same time on lavapipe on an AMD EPYC development machine).
fn neighbour_word(s: u32, w: u32, own: bool, same_class: bool) -> u32 {
    if (own) {
        if (!same_class) {
            return state[s * stride() + w];
        }
    }
    return pass_start[s * stride() + w];
}

// The projection's weights and biases (host: `projection_uniform` in
// src/gpu/projection_weights.rs), in a uniform buffer: every invocation reads the same words at
// the same time. Read from the level's storage buffer they took ~45% of the kernel on lavapipe,
// from here about a quarter: lavapipe loads each word as a scalar and broadcasts it to its 16
// lanes, and with the sums they outnumber the vector registers, so a neighbour's pass of the
// projection loop is mostly broadcasts and spills around its multiply-adds (on AMD EPYC and
// Intel Xeon development machines, BENCHMARKS.md; unrolling the loops to make the index constant
// compiled for seconds and ran slower). Vector g of plane a's bias is v[a * 4 + g] (outputs
// 4g..4g+3: sum_i mean_i * w_ji). The weights start at vector PROJECTION_BASE, laid out as
// WEIGHT_LAYOUT says:
// - PLAIN: input i's weights in per_input = ceil(PCA_OUT / 4) vectors from
//   PROJECTION_BASE + (a * pca_in + i) * per_input, vector g holding outputs 4g..4g+3.
// - HALVES (every weight fits 16 bits): the same with per_input = ceil(PCA_OUT / 8), vector h
//   holding outputs 8h..8h+3 in its low halves and 8h+4..8h+7 in its high halves (half the reads,
//   which lavapipe makes lane by lane). The default where the weights fit.
// - BYTES (every weight fits 16 bits): per plane, neighbour and pixel word, 2 * groups vectors
//   (groups = ceil(PCA_OUT / 4)): the high bytes, then the low bytes, of w + 32768 for the word's
//   four channels, component j % 4 of vector j / 4 for output j (`add_word`). For packed byte dot
//   products: on lavapipe 1.3x slower than HALVES on an AMD EPYC development machine
//   (BENCHMARKS.md), where llvmpipe expands each dot product while it runs HALVES' multiply-adds
//   as AVX-512 VNNI; for hardware GPUs with a native 4x8-bit dot product, chosen by
//   `SOLIDSYNTH_WEIGHT_LAYOUT=bytes`.
const PROJECTION_BASE: u32 = 12u;
const PROJECTION_VECTORS: u32 = 4096u;
struct ProjectionWeights {
    v: array<vec4<i32>, PROJECTION_VECTORS>,
}
@group(0) @binding(5) var<uniform> projection: ProjectionWeights;

// The CPU reference sums (x_i - mean_i) * w_ji; here sum_i x_i * w_ji - bias_j, the same value
// (it fits an i32, analysis::pca::choose_shift) reached through wrapping partial sums.
// A plane's projected neighbourhood: its PCA_OUT bytes packed 4 to a word (up to 16; zero past
// PCA_OUT), and the sum of their squares.
struct Projected {
    words: vec4<u32>,
    squares: u32,
}

// Output bytes 4g..4g+3 of a projection, those past PCA_OUT zeroed, packed into a word (x), and
// the sum of their squares (y).
fn pack_bytes(bytes: vec4<u32>, g: u32) -> vec2<u32> {
    let first = 4u * g;
    let kept = vec4<u32>(select(0u, 1u, first < PCA_OUT), select(0u, 1u, first + 1u < PCA_OUT),
        select(0u, 1u, first + 2u < PCA_OUT), select(0u, 1u, first + 3u < PCA_OUT));
    let v = bytes * kept;
    return vec2<u32>(v.x | (v.y << 8u) | (v.z << 16u) | (v.w << 24u), dot(v, v));
}

// The projection's partial sums: outputs 4g..4g+3 in s_g. Four vectors by name, not an array:
// lavapipe keeps an array indexed by a loop counter in memory (8% of the kernel at 128^3 on an
// AMD EPYC development machine, BENCHMARKS.md).
struct Sums {
    s0: vec4<i32>,
    s1: vec4<i32>,
    s2: vec4<i32>,
    s3: vec4<i32>,
}

// Input byte x times its weights (from vector `row` of the projection uniform, PLAIN or
// HALVES) added to the sums.
fn add_input(sums: ptr<function, Sums>, x: i32, row: u32) {
    let groups = (PCA_OUT + 3u) / 4u;
    if (WEIGHT_LAYOUT == HALVES) {
        // Outputs 0..7 in the first vector's halves, 8..15 in the second's.
        let first = projection.v[row];
        (*sums).s0 += x * ((first << vec4<u32>(16u)) >> vec4<u32>(16u));
        if (groups > 1u) {
            (*sums).s1 += x * (first >> vec4<u32>(16u));
        }
        if (groups > 2u) {
            let second = projection.v[row + 1u];
            (*sums).s2 += x * ((second << vec4<u32>(16u)) >> vec4<u32>(16u));
            if (groups > 3u) {
                (*sums).s3 += x * (second >> vec4<u32>(16u));
            }
        }
    } else {
        (*sums).s0 += x * projection.v[row];
        if (groups > 1u) {
            (*sums).s1 += x * projection.v[row + 1u];
        }
        if (groups > 2u) {
            (*sums).s2 += x * projection.v[row + 2u];
        }
        if (groups > 3u) {
            (*sums).s3 += x * projection.v[row + 3u];
        }
    }
}

// The projection's sums over byte weights: with W = w + 32768 = 256 H + L per weight,
// sum_i x_i w_i = 256 sum_i x_i H_i + sum_i x_i L_i - 32768 sum_i x_i, each sum taken four
// channels at a time as a packed byte dot product of a pixel word (bytes past the channels have
// H 0x80 and L 0: they cancel). Outputs 4g..4g+3 in high_g and low_g; wrapping u32 sums, as the
// plain layout's. Against multiplying byte by byte with 16-bit weights: 17 dot products per
// neighbour (three channels, eight outputs) instead of 24 multiply-adds and their unpacking.
struct ByteSums {
    high0: vec4<u32>,
    high1: vec4<u32>,
    high2: vec4<u32>,
    high3: vec4<u32>,
    low0: vec4<u32>,
    low1: vec4<u32>,
    low2: vec4<u32>,
    low3: vec4<u32>,
    bytes: u32,
}

// The four dot products of pixel word x with the four byte-weight words of w.
fn dot_weights(x: u32, w: vec4<i32>) -> vec4<u32> {
    let v = bitcast<vec4<u32>>(w);
    return vec4<u32>(dot4U8Packed(x, v.x), dot4U8Packed(x, v.y), dot4U8Packed(x, v.z),
        dot4U8Packed(x, v.w));
}

// Pixel word x of a neighbour added to the sums with its byte weights from vector `row`.
fn add_word(sums: ptr<function, ByteSums>, x: u32, row: u32) {
    let groups = (PCA_OUT + 3u) / 4u;
    let low = row + groups;
    (*sums).high0 += dot_weights(x, projection.v[row]);
    (*sums).low0 += dot_weights(x, projection.v[low]);
    if (groups > 1u) {
        (*sums).high1 += dot_weights(x, projection.v[row + 1u]);
        (*sums).low1 += dot_weights(x, projection.v[low + 1u]);
    }
    if (groups > 2u) {
        (*sums).high2 += dot_weights(x, projection.v[row + 2u]);
        (*sums).low2 += dot_weights(x, projection.v[low + 2u]);
    }
    if (groups > 3u) {
        (*sums).high3 += dot_weights(x, projection.v[row + 3u]);
        (*sums).low3 += dot_weights(x, projection.v[low + 3u]);
    }
    (*sums).bytes += dot4U8Packed(x, 0x01010101u);
}

// The voxel at (du, dv) in plane a of the voxel `r` surrounds, its pixel words added to the
// byte sums (weights from vector `row`, 2 * groups vectors per word). Absent voxels read as zero.
fn add_neighbour_words(sums: ptr<function, ByteSums>, r: Around, a: u32, du: i32, dv: i32, row: u32) {
    let s = plane_neighbour(r, a, du, dv);
    let own = in_own_brick(r, a, du, dv);
    let same_class = ((du | dv) & 1) == 0;
    let per_word = 2u * ((PCA_OUT + 3u) / 4u);
    // The first word written out, not looped over (see `add_neighbour`).
    var word = 0u;
    if (s != ABSENT) {
        word = neighbour_word(s, 3u, own, same_class);
    }
    add_word(sums, word, row);
    for (var w = 1u; w < (CHANNELS + 3u) / 4u; w++) {
        var more = 0u;
        if (s != ABSENT) {
            more = neighbour_word(s, 3u + w, own, same_class);
        }
        add_word(sums, more, row + w * per_word);
    }
}

// The voxel at (du, dv) in plane a of the voxel `r` surrounds, its channels added to the sums
// (weights from vector `row`, per_input vectors per channel). Absent voxels read as zero. The
// channels are written out rather than looped over: in a loop lavapipe blends every partial sum
// with the loop's lane mask after each multiply-add (14% of the kernel at 128^3 on an AMD EPYC
// development machine).
fn add_neighbour(sums: ptr<function, Sums>, r: Around, a: u32, du: i32, dv: i32, row: u32, per_input: u32) {
    let s = plane_neighbour(r, a, du, dv);
    let own = in_own_brick(r, a, du, dv);
    let same_class = ((du | dv) & 1) == 0;
    var word = 0u;
    if (s != ABSENT) {
        word = neighbour_word(s, 3u, own, same_class);
    }
    add_input(sums, i32(word & 0xFFu), row);
    if (CHANNELS > 1u) {
        add_input(sums, i32((word >> 8u) & 0xFFu), row + per_input);
    }
    if (CHANNELS > 2u) {
        add_input(sums, i32((word >> 16u) & 0xFFu), row + 2u * per_input);
    }
    if (CHANNELS > 3u) {
        add_input(sums, i32(word >> 24u), row + 3u * per_input);
    }
    for (var ch = 4u; ch < CHANNELS; ch++) {
        var byte = 0u;
        if (s != ABSENT) {
            byte = (neighbour_word(s, 3u + ch / 4u, own, same_class) >> ((ch % 4u) * 8u)) & 0xFFu;
        }
        add_input(sums, i32(byte), row + ch * per_input);
    }
}

fn project_plane(r: Around, a: u32) -> Projected {
    let groups = (PCA_OUT + 3u) / 4u;
    // Each output's sum starts at minus its bias.
    var sums = Sums(-projection.v[a * 4u], -projection.v[a * 4u + 1u], -projection.v[a * 4u + 2u],
        -projection.v[a * 4u + 3u]);
    if (WEIGHT_LAYOUT == BYTES) {
        let per_neighbour = ((CHANNELS + 3u) / 4u) * 2u * groups;
        var row = PROJECTION_BASE + a * 25u * per_neighbour;
        let zero = vec4<u32>(0u);
        var b = ByteSums(zero, zero, zero, zero, zero, zero, zero, zero, 0u);
        for (var dv = -2; dv <= 2; dv++) {
            for (var du = -2; du <= 2; du++) {
                add_neighbour_words(&b, r, a, du, dv, row);
                row += per_neighbour;
            }
        }
        let offsets = vec4<u32>(32768u * b.bytes);
        sums.s0 += bitcast<vec4<i32>>(256u * b.high0 + b.low0 - offsets);
        sums.s1 += bitcast<vec4<i32>>(256u * b.high1 + b.low1 - offsets);
        sums.s2 += bitcast<vec4<i32>>(256u * b.high2 + b.low2 - offsets);
        sums.s3 += bitcast<vec4<i32>>(256u * b.high3 + b.low3 - offsets);
    } else {
        let per_input = select(groups, (groups + 1u) / 2u, WEIGHT_LAYOUT == HALVES);
        let per_neighbour = CHANNELS * per_input;
        var row = PROJECTION_BASE + a * params.pca_in * per_input;
        for (var dv = -2; dv <= 2; dv++) {
            for (var du = -2; du <= 2; du++) {
                add_neighbour(&sums, r, a, du, dv, row, per_input);
                row += per_neighbour;
            }
        }
    }
    // Rounded, shifted and offset to a byte, as the CPU reference's quantization.
    let round = 1 << (params.shift - 1u);
    let shift = vec4<u32>(params.shift);
    let g0 = pack_bytes(vec4<u32>(clamp(((sums.s0 + round) >> shift) + 128, vec4<i32>(0), vec4<i32>(255))), 0u);
    let g1 = pack_bytes(vec4<u32>(clamp(((sums.s1 + round) >> shift) + 128, vec4<i32>(0), vec4<i32>(255))), 1u);
    let g2 = pack_bytes(vec4<u32>(clamp(((sums.s2 + round) >> shift) + 128, vec4<i32>(0), vec4<i32>(255))), 2u);
    let g3 = pack_bytes(vec4<u32>(clamp(((sums.s3 + round) >> shift) + 128, vec4<i32>(0), vec4<i32>(255))), 3u);
    return Projected(vec4<u32>(g0.x, g1.x, g2.x, g3.x), g0.y + g1.y + g2.y + g3.y);
}

// The first (PCA_OUT + 3) / 4 words of a projection at word `at` of the level data or of the
// candidate tables, zero past them. Written out by word count, not as a loop over a vector's
// components, which lavapipe addressed at run time. (Two functions for the two buffers: a WGSL
// function cannot take a storage buffer as a parameter.)
fn level_words(at: u32) -> vec4<u32> {
    let words = (PCA_OUT + 3u) / 4u;
    var p = vec4<u32>(level[at], 0u, 0u, 0u);
    if (words > 1u) {
        p.y = level[at + 1u];
    }
    if (words > 2u) {
        p.z = level[at + 2u];
    }
    if (words > 3u) {
        p.w = level[at + 3u];
    }
    return p;
}

fn table_words(at: u32) -> vec4<u32> {
    let words = (PCA_OUT + 3u) / 4u;
    var p = vec4<u32>(tables[at], 0u, 0u, 0u);
    if (words > 1u) {
        p.y = tables[at + 1u];
    }
    if (words > 2u) {
        p.z = tables[at + 2u];
    }
    if (words > 3u) {
        p.w = tables[at + 3u];
    }
    return p;
}

// sum_j q_j p_j over the bytes of q and of the projection words p, with packed byte dot
// products (on an NVIDIA H100 they halved the kernel's time against a loop over the bytes of an
// array of PCA_OUT i32, BENCHMARKS.md). q's bytes past PCA_OUT are zero, so p's need no mask.
fn cross(q: Projected, p: vec4<u32>) -> u32 {
    let words = (PCA_OUT + 3u) / 4u;
    var s = dot4U8Packed(q.words.x, p.x);
    if (words > 1u) {
        s += dot4U8Packed(q.words.y, p.y);
    }
    if (words > 2u) {
        s += dot4U8Packed(q.words.z, p.z);
    }
    if (words > 3u) {
        s += dot4U8Packed(q.words.w, p.w);
    }
    return s;
}

// sum_j p_j^2 over the first PCA_OUT bytes of p (the bytes past them, none at the analysis' 8 or
// 12 dimensions, masked off: the CPU reference ignores them).
fn squares(p: vec4<u32>) -> u32 {
    let words = (PCA_OUT + 3u) / 4u;
    let tail = PCA_OUT % 4u;
    let last = select((1u << (tail * 8u)) - 1u, 0xFFFFFFFFu, tail == 0u);
    var m = p;
    if (words == 1u) {
        m.x &= last;
    }
    if (words == 2u) {
        m.y &= last;
    }
    if (words == 3u) {
        m.z &= last;
    }
    if (words == 4u) {
        m.w &= last;
    }
    var s = dot4U8Packed(m.x, m.x);
    if (words > 1u) {
        s += dot4U8Packed(m.y, m.y);
    }
    if (words > 2u) {
        s += dot4U8Packed(m.z, m.z);
    }
    if (words > 3u) {
        s += dot4U8Packed(m.w, m.w);
    }
    return s;
}

// sum_j (q_j - p_j)^2 over the PCA_OUT bytes of q and of the projection of pixel c of E_a, as
// q.q + p.p - 2 q.p: exact (each sum is below 16 x 255^2, and the total, a sum of squares, is
// not negative).
fn distance(q: Projected, a: u32, c: u32) -> u32 {
    let proj = select(select(params.proj2, params.proj1, a == 1u), params.proj0, a == 0u);
    let p = level_words(proj + (u32(coord_y(c)) * params.ex.width + u32(coord_x(c))) * params.proj_words);
    return q.squares + squares(p) - 2u * cross(q, p);
}

// A candidate's scale word in the tables (src/gpu/candidate_tables.rs): its distance's scale
// (16 + usage penalties, below 2^SCALE_BITS) in the low bits, and above them the sum of squares
// of its stored projections, p.p of `distance`, computed once when the tables are built rather
// than per candidate and voxel (10% of the kernel on lavapipe on an AMD EPYC development
// machine, BENCHMARKS.md).
const SCALE_BITS: u32 = 10u;
const SCALE_MASK: u32 = (1u << SCALE_BITS) - 1u;

// Usage penalty of pixel c of E_a in sixteenths (analysis::balance): one word per pixel right
// after E_a's pixels in the level data (lazy::pack).
fn penalty(a: u32, c: u32) -> u32 {
    let pixels = select(select(params.ex.pixels2, params.ex.pixels1, a == 1u), params.ex.pixels0, a == 0u);
    let table = pixels + params.ex.width * params.ex.height * params.ex.pixel_words;
    return level[table + u32(coord_y(c)) * params.ex.width + u32(coord_x(c))];
}

// The scale of a triple's distance: 16 + the penalties of its three pixels (the scaled
// distance stays below 2^32: at most 3 x 16 x 255^2 x (16 + 3 x 255)).
fn factor(t: vec3<u32>) -> u32 {
    return 16u + penalty(0u, t.x) + penalty(1u, t.y) + penalty(2u, t.z);
}

// The best 2D candidate so far: its entry in the tables, its distance and its scaled distance.
struct Best2d {
    entry: u32,
    raw: u32,
    d: u32,
}

// The 2D candidate at entry e of the tables scored against q: kept if closer than the best.
fn score_2d(best: ptr<function, Best2d>, q: Projected, e: u32) {
    let scale = tables[e + 1u];
    let raw = q.squares + (scale >> SCALE_BITS) - 2u * cross(q, table_words(e + 2u));
    let d = raw * (scale & SCALE_MASK);
    if (d < (*best).d) {
        *best = Best2d(e, raw, d);
    }
}

// The best 2D candidate of plane a (x) and its unscaled distance (y).
fn best_2d(r: Around, a: u32, q: Projected) -> vec2<u32> {
    let table = tables[a];
    let entry = (2u + params.proj_words + 3u) & ~3u;
    // The best candidate's entry (its coordinate read once, after the search) and distances.
    var best = Best2d(ABSENT, 0u, 0xFFFFFFFFu);
    for (var dv = -1; dv <= 1; dv++) {
        for (var du = -1; du <= 1; du++) {
            // Coordinate a of the neighbour's triple (0 when its brick is not stored: only
            // voxels the plan does not need read those).
            let s = plane_neighbour(r, a, du, dv);
            var c = 0u;
            if (s != ABSENT) {
                c = neighbour_word(s, a, in_own_brick(r, a, du, dv), du == 0 && dv == 0);
            }
            let sx = coord_x(c) - du;
            let sy = coord_y(c) - dv;
            if (params.ex.border != 0u && (sx < 0 || sy < 0 || sx >= i32(params.ex.width) || sy >= i32(params.ex.height))) {
                continue;
            }
            let src = pack_coord(resolve_near(sx, params.ex.width, params.ex.border), resolve_near(sy, params.ex.height, params.ex.border));
            let list = table + (u32(coord_y(src)) * params.ex.width + u32(coord_x(src))) * K2D * entry;
            // The list's candidates in order, written out up to four.
            score_2d(&best, q, list);
            if (K2D > 1u) {
                score_2d(&best, q, list + entry);
            }
            if (K2D > 2u) {
                score_2d(&best, q, list + 2u * entry);
            }
            if (K2D > 3u) {
                score_2d(&best, q, list + 3u * entry);
            }
            for (var j = 4u; j < K2D; j++) {
                score_2d(&best, q, list + j * entry);
            }
        }
    }
    var coordinate = 0u;
    if (best.entry != ABSENT) {
        coordinate = tables[best.entry];
    }
    return vec2<u32>(coordinate, best.raw);
}

// rotate_from_shared of src/analysis/frame.rs.
fn rotate(t: vec3<u32>, a: u32) -> vec3<u32> {
    if (a == 1u) {
        return vec3<u32>(t.z, t.x, t.y);
    }
    if (a == 2u) {
        return vec3<u32>(t.y, t.z, t.x);
    }
    return t;
}

// The 3D candidates of pixel `pixel2d` of E_a (plane a's best 2D candidate, at distance `own_d`
// on that plane) scored against the voxel's projections q_next on plane (a + 1) % 3 and q_last
// on (a + 2) % 3: one closer than *best_d becomes the best (its entry and plane; the caller reads
// its triple once, after every search, rather than each candidate's as it is scored). Called
// with a constant `a`, not in a loop over the planes, whose counter lavapipe kept for run-time
// indexing.
fn search_3d(a: u32, pixel2d: u32, own_d: u32, q_next: Projected, q_last: Projected,
        best_entry: ptr<function, u32>, best_plane: ptr<function, u32>, best_d: ptr<function, u32>) {
    let entry = (4u + 2u * params.proj_words + 3u) & ~3u;
    let slots = tables[6];
    var owner = a;
    if (params.shared_sets != 0u) {
        owner = 0u;
    }
    // Every 3D candidate of pixel2d has it as its a coordinate (the .ssa reader checks it): its
    // distance on plane a is best_2d's.
    let pixel = u32(coord_y(pixel2d)) * params.ex.width + u32(coord_x(pixel2d));
    let counts = select(select(params.counts2, params.counts1, owner == 1u), params.counts0, owner == 0u);
    let count = min(level[counts + pixel], params.k3d_used);
    let list = tables[3u + owner] + pixel * slots * entry;
    // Plane a's distance and both planes' q.q, the same for every candidate.
    let fixed = own_d + q_next.squares + q_last.squares;
    for (var j = 0u; j < count; j++) {
        let e = list + j * entry;
        // The stored projections: on plane (a + 1) % 3, then (a + 2) % 3; the scale word holds
        // the sum of both's p.p.
        let next = e + 4u;
        let scale = tables[e + 3u];
        let crossed = cross(q_next, table_words(next)) + cross(q_last, table_words(next + params.proj_words));
        let d = (fixed + (scale >> SCALE_BITS) - 2u * crossed) * (scale & SCALE_MASK);
        if (d < *best_d) {
            *best_d = d;
            *best_entry = e;
            *best_plane = a;
        }
    }
}

// The voxel `r` surrounds corrected: its new triple.
fn correct_voxel(r: Around) -> vec3<u32> {
    let q0 = project_plane(r, 0u);
    let q1 = project_plane(r, 1u);
    let q2 = project_plane(r, 2u);
    let found0 = best_2d(r, 0u, q0);
    let found1 = best_2d(r, 1u, q1);
    let found2 = best_2d(r, 2u, q2);
    // Found: the best 2D candidate (x) and its distance on its own plane (y).
    var best = vec3<u32>(found0.x, found1.x, found2.x);
    if (params.mode == 0u) {
        // The voxel's current triple (active bricks are stored).
        let o = r.own + u32(r.local.z * 16 + r.local.y * 4 + r.local.x);
        best = vec3<u32>(neighbour_word(o, 0u, true, true), neighbour_word(o, 1u, true, true),
            neighbour_word(o, 2u, true, true));
        var best_d = (distance(q0, 0u, best.x) + distance(q1, 1u, best.y) + distance(q2, 2u, best.z)) * factor(best);
        // The best 3D candidate's entry and plane; its triple is read once, after the search.
        var best_entry = ABSENT;
        var best_plane = 0u;
        search_3d(0u, found0.x, found0.y, q1, q2, &best_entry, &best_plane, &best_d);
        search_3d(1u, found1.x, found1.y, q2, q0, &best_entry, &best_plane, &best_d);
        search_3d(2u, found2.x, found2.y, q0, q1, &best_entry, &best_plane, &best_d);
        if (best_entry != ABSENT) {
            best = vec3<u32>(tables[best_entry], tables[best_entry + 1u], tables[best_entry + 2u]);
            if (params.shared_sets != 0u) {
                best = rotate(best, best_plane);
            }
        }
    }
    return best;
}

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let voxel = class_voxel(gid.x + gid.y * params.grid_stride, BLOCK_BRICKS);
    let b = voxel.x;
    let k = voxel.y;
    if (b >= params.list_count) {
        return;
    }
    if (CHANNELS != params.ex.channels || PCA_OUT != params.pca_out || K2D != params.k2d) {
        return; // a pipeline built for other constants: leave the voxel as it was
    }
    if (((bricks[params.mask_offset + b / 4u] >> ((b % 4u) * 8u + k)) & 1u) == 0u) {
        return; // a voxel the plan does not need
    }
    let cls = vec3<u32>(params.class_x, params.class_y, params.class_z);
    let pos = brick_at(params.list_offset, b) * 4
        + vec3<i32>(cls + 2u * vec3<u32>(k & 1u, (k >> 1u) & 1u, k >> 2u));
    let r = around(pos);
    if (r.own == ABSENT) {
        return; // never expected: the voxels the plan needs are stored
    }
    let best = correct_voxel(r);
    let i = (r.own + u32(r.local.z * 16 + r.local.y * 4 + r.local.x)) * stride();
    state[i] = best.x;
    state[i + 1u] = best.y;
    state[i + 2u] = best.z;
    let pixels = vec3<u32>(params.ex.pixels0, params.ex.pixels1, params.ex.pixels2);
    for (var wd = 0u; wd < params.ex.pixel_words; wd++) {
        state[i + 3u + wd] = value_word(best, wd, pixels, params.ex.width, params.ex.pixel_words, params.ex.channels);
    }
}
