// Modifiability: when may the decimator touch a vertex?
//
// A vertex on a cell edge may move or vanish only once every face around it exists, i.e. once all
// four cells sharing its edge have been extracted (paper, section 3.1). The generalised rule:
//
//   After extracting cell c, the vertices on c's three min-corner edges (cell edges 0, 4, 8) are final.
//
// Proof. Cells are visited in the order of the key (bz, by, bx, cz, cy, cx): block coordinates first
// (z, then y, then x), then the cell inside its block (z, then y, then x). Let c' <= c componentwise with
// c' != c. Each block coordinate of c' is <= that of c. If some block coordinate is smaller, the first one
// that differs in key order is smaller, so c' comes first. Otherwise both lie in one block and the cell
// coordinates of c' are <= those of c with one strictly smaller, so again c' comes first. The four cells
// sharing the edge from voxel v along axis a are v - {0,1}·e_b - {0,1}·e_c (b, c the other axes): all are
// <= v componentwise, so the cell whose min corner is v is the last of them. Every cell that carries a
// vertex straddles the iso-value, so all four are in the block list and that cell is extracted. Hence
// each vertex is finalised exactly once, at that cell, whether or not its neighbours lie in other leaves.
// Nothing depends on where the blocks are, only on the monotone order, so the rule holds for the sparse
// VDB domain. (tests/test_modifiability.cpp checks it with an oracle on random sparse grids.)
//
// Integration works per block, so the pipeline applies the rule at block granularity: once block B is
// integrated, every vertex whose edge min corner lies inside B's 8^3 cells is final.
#pragma once
#include <array>
#include <cstdint>

namespace vdb_isosimp {

// Per cell edge (numbering of marching_cubes.h): does extracting the cell make that edge's vertex final?
// In the unbounded VDB domain only the min-corner edges do; a clipped domain would add rows here.
constexpr std::array<bool, 12> kFinalAfterCell = {true,  false, false, false,   // x edges
                                                  true,  false, false, false,   // y edges
                                                  true,  false, false, false};  // z edges

// Block-level form: a vertex whose edge starts at voxel `edgeMin` is final once the block with
// origin `blockOrigin` (a multiple of 8) has been integrated iff edgeMin lies in that block.
inline bool finalAfterBlock(const std::array<int32_t, 3>& edgeMin, const std::array<int32_t, 3>& blockOrigin)
{
    for (int a = 0; a < 3; ++a)
        if (edgeMin[a] < blockOrigin[a] || edgeMin[a] >= blockOrigin[a] + 8) return false;
    return true;
}

} // namespace vdb_isosimp
