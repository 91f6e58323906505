// A 64-bit digest of a cast image, so that a benchmark can tell whether two
// frames show the same pixels without reading the images back (the Fig. 9
// corruption count, docs/benchmarks.md). CPU port: `rgb_digest` in
// painter/gpu/src/digest.rs, which computes the same two words.
//
// Pixel i with sRGB bytes v = r | g << 8 | b << 16 contributes
//     a ^= fmix(v ^ fmix(i))        b += fmix(v + fmix(i ^ 0x9e3779b9))
// (fmix: MurmurHash3's 32-bit finaliser; b wraps). Both folds are
// associative and commutative, so the digest does not depend on how the
// pixels are split between invocations: each workgroup writes its pair,
// and the host folds the pairs the same way.

struct DigestParams {
    count: u32,   // pixels in the image
    stride: u32,  // invocations in the dispatch
}

@group(0) @binding(0) var<storage, read> pixels: array<u32>;
@group(0) @binding(1) var<storage, read_write> folds: array<vec2<u32>>;
@group(0) @binding(2) var<uniform> dp: DigestParams;

const DIGEST_GROUP: u32 = 256u;
var<workgroup> part: array<vec2<u32>, DIGEST_GROUP>;

fn fmix(x: u32) -> u32 {
    var h = x;
    h ^= h >> 16u;
    h *= 0x85ebca6bu;
    h ^= h >> 13u;
    h *= 0xc2b2ae35u;
    h ^= h >> 16u;
    return h;
}

@compute @workgroup_size(DIGEST_GROUP)
fn main(@builtin(global_invocation_id) gid: vec3<u32>,
        @builtin(local_invocation_index) li: u32,
        @builtin(workgroup_id) wg: vec3<u32>) {
    var a = 0u;
    var b = 0u;
    for (var i = gid.x; i < dp.count; i += dp.stride) {
        let v = pixels[i] & 0x00ffffffu;
        a ^= fmix(v ^ fmix(i));
        b += fmix(v + fmix(i ^ 0x9e3779b9u));
    }
    part[li] = vec2<u32>(a, b);
    workgroupBarrier();
    for (var s = DIGEST_GROUP / 2u; s > 0u; s >>= 1u) {
        if (li < s) {
            let o = part[li + s];
            part[li] = vec2<u32>(part[li].x ^ o.x, part[li].y + o.y);
        }
        workgroupBarrier();
    }
    if (li == 0u) {
        folds[wg.x] = part[0];
    }
}
