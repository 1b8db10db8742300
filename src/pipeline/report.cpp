#include "vdb_isosimp/vdb_isosimp.h"

namespace vdb_isosimp {

std::vector<ReportField> reportFields(const Report& r, const Options& o)
{
    using K = ReportField::Kind;
    const auto text = [](const char* name, const std::string& v) { return ReportField{name, K::Text, v, 0, 0.0}; };
    const auto integer = [](const char* name, uint64_t v) { return ReportField{name, K::Integer, {}, v, 0.0}; };
    const auto real = [](const char* name, double v) { return ReportField{name, K::Real, {}, 0, v}; };
    return {text("input", r.file),
            text("grid", r.grid),
            text("value_type", r.valueType),
            text("grid_class", r.gridClass),
            real("iso", r.iso),
            real("ratio", r.ratio),
            integer("batch", o.batchFaces),
            integer("blocks", r.blocks),
            integer("faces_full", r.facesFull),
            integer("faces_target", r.facesTarget),
            integer("faces_out", r.facesOut),
            integer("verts_out", r.vertsOut),
            integer("decimations", r.decimations),
            integer("max_intermediate_faces", r.maxIntermediateFaces),
            integer("max_uncontractible_faces", r.maxUncontractibleFaces),
            integer("components_dropped", r.componentsDropped),
            integer("components_pruned", r.componentsPruned),
            real("seconds", r.seconds),
            real("seconds_slabs", r.secondsSlabs),
            real("seconds_final", r.secondsFinal),
            real("peak_rss_mb", r.peakRssMb)};
}

} // namespace vdb_isosimp
