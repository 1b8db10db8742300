// Shared by the libFuzzer targets: the parsers read files, so each input is written to a file in a
// private temporary folder (on tmpfs when there is one) under the name the format needs.
#pragma once
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <unistd.h>

namespace fuzz {

inline const std::string& dir()
{
    static const std::string d = [] {
        std::string base = ::access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
        std::string t = base + "/vdb_isosimp_fuzz.XXXXXX";
        if (!::mkdtemp(&t[0])) std::abort();
        // Removed when the run ends (libFuzzer returns through exit()); a crash leaves it for a look. The
        // handler reads its own copy: `d` itself is destroyed before handlers registered during its
        // initialisation run.
        static const std::string* const removeAtExit = new std::string(t);
        std::atexit([] {
            std::error_code ec;
            std::filesystem::remove_all(*removeAtExit, ec);
        });
        return t;
    }();
    return d;
}

inline std::string writeFile(const std::string& name, const uint8_t* data, size_t size)
{
    const std::string path = dir() + "/" + name;
    FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) std::abort();
    if (size) std::fwrite(data, 1, size, f);
    std::fclose(f);
    return path;
}

} // namespace fuzz
