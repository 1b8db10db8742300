// Frame sequences: one path standing for numbered files, as Houdini and Blender write them. In the file
// name part of a path, a run of '#' ("smoke.####.vdb", Houdini's $F4) is the frame number padded with
// zeros to the run's length; a printf conversion ("smoke.%04d.vdb", also %d and %4d) is the number as
// printf would write it. Pure path logic (no OpenVDB), so the program, the Python module and the
// Blender add-on name and find frames by the same rule.
#pragma once
#include <optional>
#include <string>
#include <vector>

namespace vdb_isosimp {

struct FramePattern {
    std::string prefix, suffix;  // the path before and after the frame number
    int width = 1;               // the number is padded to at least this many characters
    bool zeroPad = true;         // with zeros ('#', %0Nd) or with spaces (%Nd)

    // The path of frame `frame` (>= 0).
    std::string path(int frame) const;
    // The frame a path names under this pattern, exactly as path() writes it; nullopt otherwise.
    std::optional<int> frameOf(const std::string& path) const;
};

// The frame pattern in the file name of `path` (the last one, if it has several), or nullopt when the
// path names a single file.
std::optional<FramePattern> parseFramePattern(const std::string& path);

struct Frame {
    int number = 0;
    std::string path;
};

// The frames of a sequence in increasing order. With both `first` and `last`: every frame of that
// range, whether its file exists or not (a missing one is the caller's error to report). Otherwise the
// files of the pattern's folder that the pattern names, within the bound given if any (a folder
// listing; none found gives an empty list).
// @throw InputError when the folder cannot be listed, first > last, or the range spans a million frames.
std::vector<Frame> framePaths(const FramePattern& pattern, std::optional<int> first = std::nullopt,
                              std::optional<int> last = std::nullopt);

} // namespace vdb_isosimp
