// The OpenVDB peer of `octopaint bench tree`: paints the same stroke set
// (read from the file `octopaint bench tree --write-strokes` writes) into
// OpenVDB 10 grids the way an OpenVDB program would, single-threaded, and
// prints its figures as one JSON object. Built and run by
// painter/bench/tree_vs_openvdb.sh; see docs/benchmarks.md.
//
// Per stroke: a fresh FloatGrid holds the stroke's coverage; every segment
// (the tapered capsule between consecutive samples, as octopaint paints it)
// visits the voxels of its bounding box through a ValueAccessor and keeps
// the maximum coverage (the per-stroke maximum of spec 8.8); then
// tools::compMax merges the stroke into the canvas density grid
// (density = max(density, coverage * sigma_b)). Voxels are the finest cells
// (voxel size 1 canvas unit). Colour is not painted here: the comparison
// favours OpenVDB, which does less work per voxel than octopaint.
//
// `--merge compmax` (the default) merges with tools::compMax, which walks
// the whole canvas tree per stroke; `--merge voxels` instead visits only the
// stroke grid's active voxels (ValueOnCIter) and raises the canvas through
// an accessor, the faster way to merge a small stroke into a big canvas.
//
// `--merge equal` does octopaint's work (issue 15, "equal work"): the canvas
// holds what octopaint's leaves hold, an sRGB colour in 8 bits a channel
// (packed in an Int32Grid) and an f32 extinction (a FloatGrid), the same 7
// bytes of data per voxel. Per stroke, a scratch FloatGrid keeps the stroke
// maximum a of every voxel (spec 8.8); stamping goes leaf by leaf
// (touchLeaf once per 8^3 block the capsule reaches, then direct offsets),
// and the merge blends every active scratch voxel into the canvas with
// octopaint's paint blend (spec 8.5: base = K if the voxel is empty, rgb =
// base + (K - base) a stored as round(255 v), sigma = bs + (sigma_b - bs) a
// rounded to f32). K is the stroke's colour for every primitive of these
// paint strokes, so the scratch grid needs no colour. With `--threads N`
// (N > 1) the merge is parallel with OpenVDB's own tools: the canvas grids
// take the scratch topology (topologyUnion), then a tree::LeafManager over
// the scratch leaves blends leaf by leaf through probeLeaf on TBB threads.
// Stamping stays serial: a maximum over overlapping capsules has no
// race-free split in OpenVDB's tools.
//
// `--threads N` caps TBB at N threads (default 1: every figure of the first
// three merges is single-threaded).

#include <openvdb/openvdb.h>
#include <openvdb/tools/Composite.h>
#include <openvdb/tree/LeafManager.h>
#include <sys/resource.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <limits>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

struct Stroke {
    double radius, hardness, opacity;
    std::vector<openvdb::Vec3d> samples;
};

static std::vector<Stroke> read_strokes(const char* path) {
    std::ifstream in(path);
    if (!in) {
        std::cerr << "openvdb_stamp: cannot read " << path << "\n";
        std::exit(1);
    }
    std::vector<Stroke> strokes;
    std::string line;
    while (std::getline(in, line)) {
        std::istringstream ls(line);
        if (line.rfind("stroke", 0) == 0) {
            std::string word;
            double r, g, b;
            Stroke s;
            ls >> word >> s.radius >> s.hardness >> s.opacity >> r >> g >> b;
            strokes.push_back(s);
        } else if (!line.empty()) {
            double x, y, z;
            ls >> x >> y >> z;
            strokes.back().samples.emplace_back(x, y, z);
        }
    }
    return strokes;
}

// Each stroke's colour (the `stroke R hardness opacity r g b` lines).
static std::vector<std::array<double, 3>> read_colours(const char* path) {
    std::ifstream in(path);
    std::vector<std::array<double, 3>> out;
    std::string line, word;
    double skip;
    while (std::getline(in, line)) {
        if (line.rfind("stroke", 0) != 0) continue;
        std::istringstream ls(line);
        std::array<double, 3> c;
        ls >> word >> skip >> skip >> skip >> c[0] >> c[1] >> c[2];
        out.push_back(c);
    }
    return out;
}

// Coverage of the capsule (p0, r) -> (p1, r) at x: 1 inside hardness * r,
// smoothstep to 0 at r (docs/spec.md 8.3, 8.5; constant radius and flow 1).
static inline double capsule_coverage(const openvdb::Vec3d& x, const openvdb::Vec3d& p0, const openvdb::Vec3d& d, double dd,
                                      double r, double hardness) {
    double u = dd > 0 ? std::clamp((x - p0).dot(d) / dd, 0.0, 1.0) : 0.0;
    openvdb::Vec3d e = x - (p0 + d * u);
    double rho = std::sqrt(e.dot(e)) / r;
    if (rho >= 1.0) return 0.0;
    if (rho <= hardness) return 1.0;
    double t = std::clamp((1.0 - rho) / (1.0 - hardness), 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

// Octopaint's stored colour channel: round(255 v) clamped (spec 5).
static inline int32_t quantise(double v) {
    return int32_t(std::clamp(std::floor(v * 255.0 + 0.5), 0.0, 255.0));
}

struct Rgb8 {
    double r, g, b;
    explicit Rgb8(int32_t packed)
        : r((packed & 0xFF) / 255.0), g(((packed >> 8) & 0xFF) / 255.0), b(((packed >> 16) & 0xFF) / 255.0) {}
};

// One voxel of octopaint's paint blend: before (rgb, bs), stroke colour K,
// stroke maximum a.
static inline void blend_paint(int32_t& rgb, float& sigma, const double K[3], double sigma_b, double a) {
    double bs = sigma;
    Rgb8 before(rgb);
    double base[3] = {before.r, before.g, before.b};
    if (bs == 0.0) base[0] = K[0], base[1] = K[1], base[2] = K[2];
    rgb = quantise(base[0] + (K[0] - base[0]) * a) | (quantise(base[1] + (K[1] - base[1]) * a) << 8) |
          (quantise(base[2] + (K[2] - base[2]) * a) << 16);
    sigma = float(std::min(bs + (sigma_b - bs) * a, double(std::numeric_limits<float>::max())));
}

struct Figures {
    uint64_t writes = 0, visited = 0, samples = 0;
    double stamp_s = 0, merge_s = 0;
};

// --merge equal: colour and density, per-stroke maximum, octopaint's blend.
static void paint_equal(const std::vector<Stroke>& strokes, const std::vector<std::array<double, 3>>& colours, int threads,
                        openvdb::FloatGrid& sigma_grid, openvdb::Int32Grid& rgb_grid, Figures& f) {
    using FloatLeaf = openvdb::FloatTree::LeafNodeType;
    using IntLeaf = openvdb::Int32Tree::LeafNodeType;
    for (size_t si = 0; si < strokes.size(); ++si) {
        const Stroke& s = strokes[si];
        auto a0 = std::chrono::steady_clock::now();
        openvdb::FloatGrid::Ptr scratch = openvdb::FloatGrid::create(0.0f);
        openvdb::FloatGrid::Accessor acc = scratch->getAccessor();
        for (size_t i = 0; i < s.samples.size(); ++i) {
            f.samples++;
            openvdb::Vec3d p0 = s.samples[i == 0 ? 0 : i - 1], p1 = s.samples[i];
            openvdb::Vec3d d = p1 - p0;
            double dd = d.dot(d);
            openvdb::Coord lo(int(std::floor(std::min(p0.x(), p1.x()) - s.radius)), int(std::floor(std::min(p0.y(), p1.y()) - s.radius)),
                              int(std::floor(std::min(p0.z(), p1.z()) - s.radius)));
            openvdb::Coord hi(int(std::floor(std::max(p0.x(), p1.x()) + s.radius)), int(std::floor(std::max(p0.y(), p1.y()) + s.radius)),
                              int(std::floor(std::max(p0.z(), p1.z()) + s.radius)));
            // Leaf by leaf: the 8^3 blocks the box covers.
            for (int bx = lo.x() & ~7; bx <= hi.x(); bx += 8)
                for (int by = lo.y() & ~7; by <= hi.y(); by += 8)
                    for (int bz = lo.z() & ~7; bz <= hi.z(); bz += 8) {
                        FloatLeaf* leaf = acc.probeLeaf(openvdb::Coord(bx, by, bz));
                        for (int x = std::max(bx, lo.x()); x <= std::min(bx + 7, hi.x()); ++x)
                            for (int y = std::max(by, lo.y()); y <= std::min(by + 7, hi.y()); ++y)
                                for (int z = std::max(bz, lo.z()); z <= std::min(bz + 7, hi.z()); ++z) {
                                    f.visited++;
                                    openvdb::Vec3d c(x + 0.5, y + 0.5, z + 0.5);
                                    double cov = capsule_coverage(c, p0, d, dd, s.radius, s.hardness);
                                    if (cov <= 0.0) continue;
                                    f.writes++;
                                    // Created only where the capsule reaches.
                                    if (!leaf) leaf = acc.touchLeaf(openvdb::Coord(bx, by, bz));
                                    openvdb::Index n = FloatLeaf::coordToOffset(openvdb::Coord(x, y, z));
                                    float v = float(cov);
                                    if (!leaf->isValueOn(n) || v > leaf->getValue(n)) leaf->setValueOn(n, v);
                                }
                    }
        }
        auto b0 = std::chrono::steady_clock::now();
        const double K[3] = {colours[si][0], colours[si][1], colours[si][2]};
        double sigma_b = -std::log1p(-std::min(s.opacity, 0.999)) / s.radius;
        if (threads <= 1) {
            openvdb::FloatGrid::Accessor sa = sigma_grid.getAccessor();
            openvdb::Int32Grid::Accessor ca = rgb_grid.getAccessor();
            for (auto it = scratch->cbeginValueOn(); it; ++it) {
                const openvdb::Coord& ijk = it.getCoord();
                float sigma = sa.getValue(ijk);
                int32_t rgb = ca.getValue(ijk);
                blend_paint(rgb, sigma, K, sigma_b, *it);
                sa.setValueOn(ijk, sigma);
                ca.setValueOn(ijk, rgb);
            }
        } else {
            // The canvas takes the stroke's topology (serial), then every
            // scratch leaf is blended into its canvas leaves in parallel.
            sigma_grid.tree().topologyUnion(scratch->tree());
            rgb_grid.tree().topologyUnion(scratch->tree());
            openvdb::tree::LeafManager<const openvdb::FloatTree> leaves(scratch->constTree());
            leaves.foreach(
                [&](const FloatLeaf& leaf, size_t) {
                    FloatLeaf* sl = sigma_grid.tree().probeLeaf(leaf.origin());
                    IntLeaf* cl = rgb_grid.tree().probeLeaf(leaf.origin());
                    for (auto it = leaf.cbeginValueOn(); it; ++it) {
                        openvdb::Index n = it.pos();
                        float sigma = sl->getValue(n);
                        int32_t rgb = cl->getValue(n);
                        blend_paint(rgb, sigma, K, sigma_b, *it);
                        sl->setValueOnly(n, sigma);
                        cl->setValueOnly(n, rgb);
                    }
                },
                true, 1);
        }
        auto c0 = std::chrono::steady_clock::now();
        f.stamp_s += std::chrono::duration<double>(b0 - a0).count();
        f.merge_s += std::chrono::duration<double>(c0 - b0).count();
    }
}

static double peak_rss_mib() {
    struct rusage u;
    getrusage(RUSAGE_SELF, &u);
    return u.ru_maxrss / 1024.0;  // KiB on Linux
}

int main(int argc, char** argv) {
    std::string merge = "compmax";
    int threads = 1;
    for (int i = 2; i + 1 < argc; i += 2) {
        std::string k = argv[i];
        if (k == "--merge") merge = argv[i + 1];
        else if (k == "--threads") threads = std::atoi(argv[i + 1]);
        else argc = 0;
    }
    if (argc < 2 || argc % 2 != 0 || threads < 1 || (merge != "compmax" && merge != "voxels" && merge != "equal")) {
        std::cerr << "usage: openvdb_stamp STROKES.txt [--merge compmax|voxels|equal] [--threads N]\n";
        return 2;
    }
    bool merge_voxels = merge == "voxels";
    tbb::global_control cap(tbb::global_control::max_allowed_parallelism, threads);
    openvdb::initialize();
    std::vector<Stroke> strokes = read_strokes(argv[1]);
    if (merge == "equal") {
        openvdb::FloatGrid::Ptr sigma_grid = openvdb::FloatGrid::create(0.0f);
        openvdb::Int32Grid::Ptr rgb_grid = openvdb::Int32Grid::create(0);
        Figures f;
        auto t0 = std::chrono::steady_clock::now();
        paint_equal(strokes, read_colours(argv[1]), threads, *sigma_grid, *rgb_grid, f);
        double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        uint64_t active = sigma_grid->activeVoxelCount();
        uint64_t mem = sigma_grid->memUsage() + rgb_grid->memUsage();
        // What was painted, summed in the trees' own (deterministic) order:
        // equal for any thread count, and comparable with octopaint's.
        double sigma_sum = 0;
        uint64_t rgb_sum = 0;
        for (auto it = sigma_grid->cbeginValueOn(); it; ++it) sigma_sum += *it;
        for (auto it = rgb_grid->cbeginValueOn(); it; ++it) rgb_sum += (*it & 0xFF) + ((*it >> 8) & 0xFF) + ((*it >> 16) & 0xFF);
        std::printf(
            "{\"impl\": \"openvdb\", \"merge\": \"equal\", \"threads\": %d, \"version\": \"%s\", \"strokes\": %zu, "
            "\"samples\": %llu, \"seconds\": %.4f, \"voxel_writes\": %llu, \"voxel_writes_per_s\": %.0f, \"voxels_visited\": %llu, "
            "\"stamp_seconds\": %.4f, \"merge_seconds\": %.4f, \"active_voxels\": %llu, \"leaf_nodes\": %llu, "
            "\"bytes_per_voxel\": %.2f, \"mem_bytes\": %llu, \"peak_rss_mib\": %.1f, \"sigma_sum\": %.6e, \"rgb_sum\": %llu}\n",
            threads, openvdb::getLibraryVersionString(), strokes.size(), (unsigned long long)f.samples, seconds,
            (unsigned long long)f.writes, f.writes / seconds, (unsigned long long)f.visited, f.stamp_s, f.merge_s,
            (unsigned long long)active, (unsigned long long)sigma_grid->tree().leafCount(),
            active ? double(mem) / double(active) : 0.0, (unsigned long long)mem, peak_rss_mib(), sigma_sum,
            (unsigned long long)rgb_sum);
        return 0;
    }
    openvdb::FloatGrid::Ptr canvas = openvdb::FloatGrid::create(0.0f);
    uint64_t writes = 0, visited = 0, samples = 0;
    double stamp_s = 0, merge_s = 0;
    auto t0 = std::chrono::steady_clock::now();
    for (const Stroke& s : strokes) {
        auto a = std::chrono::steady_clock::now();
        openvdb::FloatGrid::Ptr stroke = openvdb::FloatGrid::create(0.0f);
        openvdb::FloatGrid::Accessor acc = stroke->getAccessor();
        double sigma_b = -std::log1p(-std::min(s.opacity, 0.999)) / s.radius;
        for (size_t i = 0; i < s.samples.size(); ++i) {
            samples++;
            openvdb::Vec3d p0 = s.samples[i == 0 ? 0 : i - 1], p1 = s.samples[i];
            openvdb::Vec3d d = p1 - p0;
            double dd = d.dot(d);
            openvdb::Vec3d lo = openvdb::Vec3d(std::min(p0.x(), p1.x()), std::min(p0.y(), p1.y()), std::min(p0.z(), p1.z())) - s.radius;
            openvdb::Vec3d hi = openvdb::Vec3d(std::max(p0.x(), p1.x()), std::max(p0.y(), p1.y()), std::max(p0.z(), p1.z())) + s.radius;
            openvdb::Coord ijk;
            // Voxel (i, j, k) covers [i, i+1)^3; it is sampled at its centre.
            for (ijk.x() = int(std::floor(lo.x())); ijk.x() <= int(std::floor(hi.x())); ++ijk.x())
                for (ijk.y() = int(std::floor(lo.y())); ijk.y() <= int(std::floor(hi.y())); ++ijk.y())
                    for (ijk.z() = int(std::floor(lo.z())); ijk.z() <= int(std::floor(hi.z())); ++ijk.z()) {
                        visited++;
                        openvdb::Vec3d x(ijk.x() + 0.5, ijk.y() + 0.5, ijk.z() + 0.5);
                        double cov = capsule_coverage(x, p0, d, dd, s.radius, s.hardness);
                        if (cov <= 0.0) continue;
                        float v = float(cov * sigma_b);
                        if (v > acc.getValue(ijk)) {
                            acc.setValue(ijk, v);
                        }
                        writes++;
                    }
        }
        auto b = std::chrono::steady_clock::now();
        if (merge_voxels) {
            openvdb::FloatGrid::Accessor out = canvas->getAccessor();
            for (auto it = stroke->cbeginValueOn(); it; ++it) {
                if (*it > out.getValue(it.getCoord())) out.setValue(it.getCoord(), *it);
            }
        } else {
            openvdb::tools::compMax(*canvas, *stroke);
        }
        auto c = std::chrono::steady_clock::now();
        stamp_s += std::chrono::duration<double>(b - a).count();
        merge_s += std::chrono::duration<double>(c - b).count();
    }
    double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    uint64_t active = canvas->activeVoxelCount();
    uint64_t mem = canvas->memUsage();
    std::printf(
        "{\"impl\": \"openvdb\", \"merge\": \"%s\", \"version\": \"%s\", \"strokes\": %zu, \"samples\": %llu, \"seconds\": %.4f, "
        "\"voxel_writes\": %llu, \"voxel_writes_per_s\": %.0f, \"voxels_visited\": %llu, \"stamp_seconds\": %.4f, "
        "\"merge_seconds\": %.4f, \"active_voxels\": %llu, \"bytes_per_voxel\": %.2f, \"mem_bytes\": %llu, \"peak_rss_mib\": %.1f}\n",
        merge.c_str(), openvdb::getLibraryVersionString(), strokes.size(), (unsigned long long)samples, seconds,
        (unsigned long long)writes, writes / seconds, (unsigned long long)visited, stamp_s, merge_s,
        (unsigned long long)active, active ? double(mem) / double(active) : 0.0, (unsigned long long)mem, peak_rss_mib());
    return 0;
}
