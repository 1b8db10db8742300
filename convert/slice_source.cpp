#include "slice_source.h"

#include "dicom_series.h"
#include "tiff_stack.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <dirent.h>
#include <sys/stat.h>
#include <vector>

namespace vdb_isosimp {

namespace {

bool isDirectory(const std::string& path)
{
    struct stat st {};
    return ::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

std::string lowerExtension(const std::string& path)
{
    const auto slash = path.find_last_of('/');
    const auto dot = path.find_last_of('.');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
    std::string e = path.substr(dot);
    for (char& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return e;
}

/// The regular files directly in `folder` (hidden files skipped), full paths.
std::vector<std::string> listFiles(const std::string& folder)
{
    DIR* dir = ::opendir(folder.c_str());
    if (!dir) throw RawInputError(folder, std::string("cannot read the folder: ") + std::strerror(errno));
    std::vector<std::string> files;
    const std::string prefix = folder.back() == '/' ? folder : folder + "/";
    while (const dirent* e = ::readdir(dir)) {
        if (e->d_name[0] == '.') continue;
        const std::string path = prefix + e->d_name;
        struct stat st {};
        if (::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode)) files.push_back(path);
    }
    ::closedir(dir);
    std::sort(files.begin(), files.end(), naturalLess);
    return files;
}

} // namespace

bool naturalLess(const std::string& a, const std::string& b)
{
    std::size_t i = 0, j = 0;
    while (i < a.size() && j < b.size()) {
        const bool da = std::isdigit(static_cast<unsigned char>(a[i])) != 0, db = std::isdigit(static_cast<unsigned char>(b[j])) != 0;
        if (da && db) {
            // Compare the digit runs by value: skip leading zeros, then the longer run is larger.
            std::size_t i0 = i, j0 = j;
            while (i0 < a.size() && a[i0] == '0') ++i0;
            while (j0 < b.size() && b[j0] == '0') ++j0;
            std::size_t i1 = i0, j1 = j0;
            while (i1 < a.size() && std::isdigit(static_cast<unsigned char>(a[i1]))) ++i1;
            while (j1 < b.size() && std::isdigit(static_cast<unsigned char>(b[j1]))) ++j1;
            if (i1 - i0 != j1 - j0) return i1 - i0 < j1 - j0;
            const int c = a.compare(i0, i1 - i0, b, j0, j1 - j0);
            if (c != 0) return c < 0;
            if (i1 - i != j1 - j) return i1 - i < j1 - j;  // "01" after "1": fewer leading zeros first
            i = i1;
            j = j1;
        } else {
            if (a[i] != b[j]) return static_cast<unsigned char>(a[i]) < static_cast<unsigned char>(b[j]);
            ++i;
            ++j;
        }
    }
    return a.size() - i < b.size() - j;
}

bool isSliceStackInput(const std::string& input)
{
    if (isDirectory(input)) return true;
    const std::string e = lowerExtension(input);
    return e == ".tif" || e == ".tiff";
}

std::unique_ptr<SliceSource> openSliceSource(const std::string& input, const SliceSourceOptions& options)
{
    if (!isDirectory(input)) {
        struct stat st {};
        if (::stat(input.c_str(), &st) != 0) throw RawInputError(input, std::string("cannot open: ") + std::strerror(errno));
        if (!options.series.empty()) throw RawInputError(input, "--series applies to a folder of DICOM files");
        return openTiffFile(input);
    }
    std::vector<std::string> dicom, tiff;
    for (const auto& f : listFiles(input)) {
        if (looksLikeTiff(f)) tiff.push_back(f);
        else if (looksLikeDicom(f)) dicom.push_back(f);
    }
    if (dicom.empty() && tiff.empty()) throw RawInputError(input, "no image: the folder holds no DICOM or TIFF file");
    if (!dicom.empty() && !tiff.empty())
        throw RawInputError(input, "the folder holds both DICOM (" + std::to_string(dicom.size()) + ") and TIFF (" +
                                       std::to_string(tiff.size()) + ") files: keep one kind");
    if (!options.series.empty() && dicom.empty()) throw RawInputError(input, "--series applies to DICOM folders; this one holds TIFF files");
    if (!dicom.empty()) return openDicomSeries(input, dicom, options.series);
    return openTiffFolder(input, std::move(tiff));
}

} // namespace vdb_isosimp
