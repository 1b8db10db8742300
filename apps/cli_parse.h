// The programs' one way of reading their command line: --help prints and exits 0, a usage error is one
// line naming the program and exit code 2.
#pragma once
#include <CLI/CLI.hpp>

#include <iostream>

namespace vdb_isosimp {

// Parses argv into `app`. Returns -1 when the program goes on, else the exit code to return.
inline int parseCommandLine(CLI::App& app, int argc, char** argv, const char* program)
{
    try {
        app.parse(argc, argv);
        return -1;
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {  // usage errors: exit 2; file errors are the program's: exit 1
        std::cerr << program << ": " << e.what() << " (see --help)\n";
        return 2;
    }
}

} // namespace vdb_isosimp
