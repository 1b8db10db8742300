// libFuzzer target: the command-line parsers of numbers and lists (cli_numbers.h: raw2vdb's
// --dims/--spacing/--origin/--clamp lists, vdb_isosimp's --max-memory), scalar type names, and
// CLI11's conversion of the numeric options vdb_isosimp declares (--iso, --ratio, --faces,
// --batch, --threads) with the same checks.
#include "cli_numbers.h"
#include "raw_header.h"

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdint>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    const std::string text(reinterpret_cast<const char*>(data), size);
    try {
        const auto d = vdb_isosimp::parseNumberList<uint64_t>("--dims", text, 3, true);
        if (d.size() != 3) __builtin_trap();
    } catch (const vdb_isosimp::CliUsageError&) {
    }
    try {
        const auto v = vdb_isosimp::parseNumberList<double>("--spacing", text, 3, false);
        if (v.size() != 3) __builtin_trap();
    } catch (const vdb_isosimp::CliUsageError&) {
    }
    try {
        vdb_isosimp::parseNumberList<double>("--clamp", text, 2, false);
    } catch (const vdb_isosimp::CliUsageError&) {
    }
    uint64_t bytes = 0;
    if (vdb_isosimp::parseMemorySize(text, bytes) && text.find_first_of("0123456789") == std::string::npos) __builtin_trap();
    vdb_isosimp::parseScalarType(text);

    // CLI11 on the same value for each numeric option of vdb_isosimp.
    for (const char* name : {"--iso", "--ratio", "--faces", "--batch", "--threads"}) {
        CLI::App app;
        double iso = 0, ratio = 0.2;
        uint64_t faces = 0, batch = 100000;
        int threads = 0;
        app.add_option("--iso", iso);
        app.add_option("--ratio", ratio)->check(CLI::Range(0.0, 1.0));
        app.add_option("--faces", faces)->check(CLI::PositiveNumber);
        app.add_option("--batch", batch)->check(CLI::Range(uint64_t(1000), uint64_t(1) << 40));
        app.add_option("--threads", threads)->check(CLI::Range(0, 1024));
        std::vector<std::string> args{text, name};  // CLI11 parses a reversed vector
        try {
            app.parse(args);
        } catch (const CLI::ParseError&) {
            continue;
        }
        if (batch < 1000 || threads < 0 || threads > 1024) __builtin_trap();
        if (!std::isnan(ratio) && (ratio < 0.0 || ratio > 1.0)) __builtin_trap();
    }
    return 0;
}
