#include "vdb_isosimp/frame_sequence.h"

#include "vdb_isosimp/errors.h"

#include <algorithm>
#include <cctype>
#include <climits>
#include <filesystem>
#include <system_error>

namespace vdb_isosimp {

namespace {

// Where the file name starts: patterns in folder names are not frame numbers.
size_t fileNameStart(const std::string& path)
{
    const size_t slash = path.find_last_of('/');
    return slash == std::string::npos ? 0 : slash + 1;
}

// A printf conversion %d, %Nd or %0Nd at `at` (a '%'): its length, or 0 when it is none of these.
size_t printfConversion(const std::string& s, size_t at, FramePattern& p)
{
    size_t i = at + 1;
    p.zeroPad = i < s.size() && s[i] == '0';
    if (p.zeroPad) ++i;
    int width = 0;
    for (; i < s.size() && std::isdigit(static_cast<unsigned char>(s[i])); ++i) {
        width = width * 10 + (s[i] - '0');
        if (width > 18) return 0;
    }
    if (i >= s.size() || s[i] != 'd') return 0;
    p.width = std::max(width, 1);
    return i + 1 - at;
}

} // namespace

std::string FramePattern::path(int frame) const
{
    std::string digits = std::to_string(frame);
    if (int(digits.size()) < width) digits.insert(0, size_t(width) - digits.size(), zeroPad ? '0' : ' ');
    return prefix + digits + suffix;
}

std::optional<int> FramePattern::frameOf(const std::string& p) const
{
    if (p.size() <= prefix.size() + suffix.size() || p.compare(0, prefix.size(), prefix) != 0 ||
        p.compare(p.size() - suffix.size(), suffix.size(), suffix) != 0)
        return std::nullopt;
    const std::string middle = p.substr(prefix.size(), p.size() - prefix.size() - suffix.size());
    const size_t first = middle.find_first_not_of(' ');
    if (first == std::string::npos || middle.size() - first > 9) return std::nullopt;
    int frame = 0;
    for (size_t i = first; i < middle.size(); ++i) {
        if (!std::isdigit(static_cast<unsigned char>(middle[i]))) return std::nullopt;
        frame = frame * 10 + (middle[i] - '0');
    }
    if (path(frame) != p) return std::nullopt;  // smoke.01.vdb is not frame 1 of smoke.####.vdb
    return frame;
}

std::optional<FramePattern> parseFramePattern(const std::string& path)
{
    const size_t name = fileNameStart(path);
    // The last pattern of the name: a frame number usually sits just before the extension.
    for (size_t i = path.size(); i-- > name;) {
        FramePattern p;
        if (path[i] == '#') {
            size_t begin = i;
            while (begin > name && path[begin - 1] == '#') --begin;
            p.width = int(i + 1 - begin);
            p.prefix = path.substr(0, begin);
            p.suffix = path.substr(i + 1);
            return p;
        }
        if (path[i] == '%' && (i == name || path[i - 1] != '%')) {
            if (const size_t n = printfConversion(path, i, p)) {
                p.prefix = path.substr(0, i);
                p.suffix = path.substr(i + n);
                return p;
            }
        }
    }
    return std::nullopt;
}

std::vector<Frame> framePaths(const FramePattern& pattern, std::optional<int> first, std::optional<int> last)
{
    if (first && *first < 0) throw InputError("frame numbers start at 0, got " + std::to_string(*first));
    if (first && last && *first > *last)
        throw InputError("the first frame (" + std::to_string(*first) + ") comes after the last (" +
                         std::to_string(*last) + ")");
    // A typing slip such as 1-100000000 would list paths for a long while before the first frame runs.
    constexpr int kMaxRange = 1000000;
    if (first && last && *last - *first >= kMaxRange)
        throw InputError("the range " + std::to_string(*first) + "-" + std::to_string(*last) + " spans more than " +
                         std::to_string(kMaxRange) + " frames");
    std::vector<Frame> frames;
    if (first && last) {
        for (int f = *first; f <= *last; ++f) frames.push_back({f, pattern.path(f)});
        return frames;
    }
    // The folder is listed as the pattern spells it, and each match is named the same way.
    const size_t name = fileNameStart(pattern.prefix);
    const std::string folder = pattern.prefix.substr(0, name);
    std::error_code ec;
    std::filesystem::directory_iterator it(folder.empty() ? "." : folder, ec), end;
    if (ec) throw InputError((folder.empty() ? "." : folder) + ": cannot list the folder (" + ec.message() + ")");
    for (; it != end; it.increment(ec)) {
        const std::optional<int> f = pattern.frameOf(folder + it->path().filename().string());
        if (f && (!first || *f >= *first) && (!last || *f <= *last)) frames.push_back({*f, pattern.path(*f)});
    }
    if (ec) throw InputError((folder.empty() ? "." : folder) + ": cannot list the folder (" + ec.message() + ")");
    std::sort(frames.begin(), frames.end(), [](const Frame& a, const Frame& b) { return a.number < b.number; });
    return frames;
}

} // namespace vdb_isosimp
