// The name of the temporary file a program writes before renaming it over its output: beside the
// output (same folder, so the rename is atomic), unique per process. The writers use it, and the
// programs' interrupt handlers remove it; one definition keeps them agreeing.
#pragma once
#include <string>
#include <unistd.h>

namespace vdb_isosimp {

inline std::string temporaryPathFor(const std::string& path)
{
    return path + ".tmp." + std::to_string(static_cast<long>(::getpid()));
}

} // namespace vdb_isosimp
