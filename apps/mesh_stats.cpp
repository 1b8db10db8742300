// mesh_stats: topology and geometry statistics of a triangle mesh file (sizes, boundary,
// non-manifold and misoriented elements, components, Euler characteristic, volume, area,
// triangle quality, bounding box).
#include "cli_parse.h"
#include "json_text.h"
#include "mesh_io.h"
#include "mesh_stats.h"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>
#include <string>

using namespace vdb_isosimp;

namespace {

} // namespace

int main(int argc, char** argv) {
    CLI::App app{"Prints topology and geometry statistics of a triangle mesh (PLY, OBJ, STL or OFF),\n"
                 "computed on the file's index arrays as stored. An edge is boundary with 1 face,\n"
                 "non-manifold with more than 2, misoriented when its 2 faces traverse it in the same\n"
                 "direction; a vertex is non-manifold when its faces form more than one fan.\n"
                 "Components are groups of faces connected through shared vertices."};
    std::string path;
    bool json = false;
    double eps = 0;
    app.add_option("mesh", path, "Mesh file")->required();
    app.add_flag("--json", json, "Print one JSON object instead of the list");
    app.add_option("--zero-area-eps", eps,
                   "Faces with area <= this (absolute, squared units) count as zero-area; 0 = exactly zero")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    if (const int code = parseCommandLine(app, argc, argv, "mesh_stats"); code >= 0) return code;

    try {
        const Mesh mesh = eval::readMesh(path);
        const eval::MeshStats s = eval::computeMeshStats(mesh, eps);
        if (json) {
            std::printf("{\n  \"file\": %s,\n", jsonString(path).c_str());
            std::printf("  \"vertices\": %zu,\n  \"faces\": %zu,\n  \"referenced_vertices\": %zu,\n  \"edges\": %zu,\n",
                        s.vertices, s.faces, s.referencedVertices, s.edges);
            std::printf("  \"boundary_edges\": %zu,\n  \"non_manifold_edges\": %zu,\n  \"misoriented_edges\": %zu,\n",
                        s.boundaryEdges, s.nonManifoldEdges, s.misorientedEdges);
            std::printf("  \"non_manifold_vertices\": %zu,\n  \"zero_area_faces\": %zu,\n  \"components\": %zu,\n",
                        s.nonManifoldVertices, s.zeroAreaFaces, s.components);
            std::printf("  \"euler_characteristic\": %ld,\n  \"closed\": %s,\n  \"manifold\": %s,\n  \"oriented\": %s,\n",
                        s.eulerCharacteristic, s.closed() ? "true" : "false", s.manifold() ? "true" : "false",
                        s.oriented() ? "true" : "false");
            std::printf("  \"signed_volume\": %.9g,\n  \"area\": %.9g,\n", s.signedVolume, s.area);
            std::printf("  \"min_angle_p1\": %.6g,\n  \"min_angle_p5\": %.6g,\n  \"min_angle_p50\": %.6g,\n",
                        s.minAngleP1, s.minAngleP5, s.minAngleP50);
            std::printf("  \"bbox_min\": [%.9g, %.9g, %.9g],\n  \"bbox_max\": [%.9g, %.9g, %.9g],\n",
                        s.bboxMin[0], s.bboxMin[1], s.bboxMin[2], s.bboxMax[0], s.bboxMax[1], s.bboxMax[2]);
            std::printf("  \"bbox_diagonal\": %.9g\n}\n", s.bboxDiagonal);
        } else {
            std::printf("file                   %s\n", path.c_str());
            std::printf("vertices               %zu (%zu referenced)\n", s.vertices, s.referencedVertices);
            std::printf("faces                  %zu\n", s.faces);
            std::printf("edges                  %zu\n", s.edges);
            std::printf("boundary edges         %zu\n", s.boundaryEdges);
            std::printf("non-manifold edges     %zu\n", s.nonManifoldEdges);
            std::printf("misoriented edges      %zu\n", s.misorientedEdges);
            std::printf("non-manifold vertices  %zu\n", s.nonManifoldVertices);
            std::printf("zero-area faces        %zu (area <= %g)\n", s.zeroAreaFaces, eps);
            std::printf("components             %zu\n", s.components);
            std::printf("Euler characteristic   %ld\n", s.eulerCharacteristic);
            std::printf("closed / manifold / oriented   %s / %s / %s\n", s.closed() ? "yes" : "no",
                        s.manifold() ? "yes" : "no", s.oriented() ? "yes" : "no");
            std::printf("signed volume          %.9g\n", s.signedVolume);
            std::printf("area                   %.9g\n", s.area);
            std::printf("min angle P1/P5/P50    %.3f / %.3f / %.3f degrees\n", s.minAngleP1, s.minAngleP5,
                        s.minAngleP50);
            std::printf("bbox min               %.9g %.9g %.9g\n", s.bboxMin[0], s.bboxMin[1], s.bboxMin[2]);
            std::printf("bbox max               %.9g %.9g %.9g\n", s.bboxMax[0], s.bboxMax[1], s.bboxMax[2]);
            std::printf("bbox diagonal          %.9g\n", s.bboxDiagonal);
        }
    } catch (const std::exception& e) {
        std::cerr << "mesh_stats: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
