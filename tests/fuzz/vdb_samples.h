// Small .vdb files covering the ways OpenVDB stores a scalar grid: blosc, zip and no compression,
// with and without active-mask compression, half floats, float and double, level sets, fog volumes
// and grids of no class, one grid or several (a vector grid and an empty one among them, and names
// with dots), and files written as a stream (no grid offsets). The mutation test (tests/test_damaged_vdb.cpp) damages them; the committed fuzz corpus
// (tests/fuzz/corpus/vdb_read) is these files, written by `test_hostile --gtest_filter='*WriteCorpus*'`
// with VDB_ISOSIMP_CORPUS_DIR set.
#pragma once
#include <openvdb/openvdb.h>
#include <openvdb/io/File.h>
#include <openvdb/io/Stream.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

namespace vdb_samples {

struct Sample {
    std::string name;
    std::function<void(const std::string& path)> write;
};

inline openvdb::FloatGrid::Ptr sphere(float radius = 5.0f)
{
    auto g = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(radius, openvdb::Vec3f(9.5f, 8.0f, 8.5f),
                                                                      1.0f, 2.0f);
    g->setName("surface");
    return g;
}

// A smooth blob of density in [0, 1] over a 14^3 box straddling leaf boundaries. Everything lies in
// one upper node (positive coordinates below 4096), which keeps the files small.
inline openvdb::FloatGrid::Ptr fog(openvdb::GridClass cls = openvdb::GRID_FOG_VOLUME)
{
    auto g = openvdb::FloatGrid::create(0.0f);
    g->setName("density");
    g->setGridClass(cls);
    auto acc = g->getAccessor();
    for (int z = 1; z < 15; ++z)
        for (int y = 1; y < 15; ++y)
            for (int x = 1; x < 15; ++x) {
                const double r = std::sqrt(double((x - 8) * (x - 8) + (y - 8) * (y - 8) + (z - 8) * (z - 8)));
                acc.setValueOn(openvdb::Coord(x, y, z), float(std::max(0.0, 1.0 - r / 7.0)));
            }
    return g;
}

inline void write(const std::string& path, const openvdb::GridPtrVec& grids, uint32_t compression)
{
    openvdb::initialize();
    openvdb::io::File f(path);
    f.setCompression(compression);
    f.write(grids);
    f.close();
}

// As io::Stream writes it (a pipe, or a file written through a stream): no grid offsets, and
// OpenVDB reads every grid, voxels included, when it opens the file.
inline void writeStream(const std::string& path, const openvdb::GridPtrVec& grids, uint32_t compression)
{
    openvdb::initialize();
    std::ofstream os(path, std::ios::binary | std::ios::trunc);
    openvdb::io::Stream s(os);
    s.setCompression(compression);
    s.write(grids);
}

template <typename GridT>
typename GridT::Ptr half(typename GridT::Ptr g)
{
    g->setSaveFloatAsHalf(true);
    return g;
}

inline std::vector<Sample> samples()
{
    using namespace openvdb::io;
    const uint32_t blosc = COMPRESS_BLOSC | COMPRESS_ACTIVE_MASK, zip = COMPRESS_ZIP | COMPRESS_ACTIVE_MASK;
    std::vector<Sample> s;
    s.push_back({"levelset_blosc", [=](const std::string& p) { write(p, {sphere()}, blosc); }});
    s.push_back({"levelset_half_blosc", [=](const std::string& p) { write(p, {half<openvdb::FloatGrid>(sphere())}, blosc); }});
    s.push_back({"levelset_none", [](const std::string& p) { write(p, {sphere()}, COMPRESS_NONE); }});
    s.push_back({"fog_blosc", [=](const std::string& p) { write(p, {fog()}, blosc); }});
    s.push_back({"fog_half_none_mask", [](const std::string& p) {
                     write(p, {half<openvdb::FloatGrid>(fog())}, COMPRESS_ACTIVE_MASK);
                 }});
    // OpenVDB zips grids of no class only (level sets and fog volumes lose the zip flag).
    s.push_back({"unknown_zip", [=](const std::string& p) { write(p, {fog(openvdb::GRID_UNKNOWN)}, zip); }});
    s.push_back({"unknown_half_zip", [=](const std::string& p) {
                     write(p, {half<openvdb::FloatGrid>(fog(openvdb::GRID_UNKNOWN))}, zip);
                 }});
    s.push_back({"double_levelset_blosc_nomask", [](const std::string& p) {
                     auto d = openvdb::tools::createLevelSetSphere<openvdb::DoubleGrid>(4.0, openvdb::Vec3f(8.0f), 1.0, 2.0);
                     d->setName("surface.double");
                     write(p, {d}, COMPRESS_BLOSC);
                 }});
    s.push_back({"several_grids_blosc", [=](const std::string& p) {
                     auto vel = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
                     vel->setName("vel");
                     vel->tree().setValue(openvdb::Coord(1, 2, 3), openvdb::Vec3s(1.0f, 0.0f, 0.0f));
                     auto empty = openvdb::FloatGrid::create(0.0f);
                     empty->setName("empty");
                     auto temperature = half<openvdb::FloatGrid>(fog());
                     temperature->setName("temperature");
                     write(p, {vel, sphere(4.0f), temperature, fog(), empty}, blosc);
                 }});
    s.push_back({"stream_unknown_zip", [=](const std::string& p) { writeStream(p, {fog(openvdb::GRID_UNKNOWN)}, zip); }});
    s.push_back({"stream_two_grids_blosc", [=](const std::string& p) {
                     auto temperature = half<openvdb::FloatGrid>(fog());
                     temperature->setName("temperature");
                     writeStream(p, {sphere(4.0f), temperature}, blosc);
                 }});
    return s;
}

} // namespace vdb_samples
