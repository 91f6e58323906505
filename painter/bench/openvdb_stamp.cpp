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
// TBB is limited to one thread: every figure is single-threaded.

#include <openvdb/openvdb.h>
#include <openvdb/tools/Composite.h>
#include <tbb/global_control.h>

#include <algorithm>
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

int main(int argc, char** argv) {
    bool merge_voxels = false;
    if (argc == 4 && std::string(argv[2]) == "--merge") {
        merge_voxels = std::string(argv[3]) == "voxels";
    } else if (argc != 2) {
        std::cerr << "usage: openvdb_stamp STROKES.txt [--merge compmax|voxels]\n";
        return 2;
    }
    tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
    openvdb::initialize();
    std::vector<Stroke> strokes = read_strokes(argv[1]);
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
        "\"merge_seconds\": %.4f, \"active_voxels\": %llu, \"bytes_per_voxel\": %.2f, \"mem_bytes\": %llu}\n",
        merge_voxels ? "voxels" : "compmax", openvdb::getLibraryVersionString(), strokes.size(), (unsigned long long)samples, seconds,
        (unsigned long long)writes, writes / seconds, (unsigned long long)visited, stamp_s, merge_s,
        (unsigned long long)active, active ? double(mem) / double(active) : 0.0, (unsigned long long)mem);
    return 0;
}
