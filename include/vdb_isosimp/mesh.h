// Indexed triangle mesh: the one mesh type every stage hands to the next (writer, evaluation tools,
// tests). World-space float positions, counter-clockwise triangles seen from outside.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace vdb_isosimp {

// Values attached to every vertex (a grid sampled at the vertices): `components` floats per point,
// point after point.
struct VertexAttribute {
    std::string name;
    uint32_t components = 1;
    std::vector<float> values;
};

struct Mesh {
    std::vector<std::array<float, 3>> points;
    std::vector<std::array<uint32_t, 3>> triangles;
    std::vector<VertexAttribute> attributes;  // empty unless asked for (Options::attributes)
};

} // namespace vdb_isosimp
