// A merge tree node's result as bytes, for the processes of a distributed run (one machine's byte
// order and type sizes on both ends, as MPI ranks of one build are). The bytes carry everything
// Integrator::absorbSlab reads, so a piece absorbed after the trip gives the same mesh as at home.
#pragma once
#include "core/schedule.h"

#include <cstddef>
#include <vector>

namespace vdb_isosimp {

// Appends the piece to `out`, freeing its parts as they are written.
void writePieceBytes(SlabPiece&& piece, std::vector<char>& out);

// Reads a piece written by writePieceBytes. @throw std::runtime_error when the bytes end early or do
// not start like a piece.
SlabPiece readPieceBytes(const char* bytes, size_t size);

} // namespace vdb_isosimp
