// Indexed triangle mesh: the one mesh type every stage hands to the next (writer, evaluation tools,
// tests). World-space float positions, counter-clockwise triangles seen from outside.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

namespace vdb_isosimp {

struct Mesh {
    std::vector<std::array<float, 3>> points;
    std::vector<std::array<uint32_t, 3>> triangles;
};

} // namespace vdb_isosimp
