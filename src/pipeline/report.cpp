#include "vdb_isosimp/vdb_isosimp.h"

namespace vdb_isosimp {

std::vector<ReportField> reportFields(const Report& r, const Options& o)
{
    using K = ReportField::Kind;
    const auto text = [](const char* name, const std::string& v) { return ReportField{name, K::Text, v, 0, 0.0}; };
    const auto integer = [](const char* name, uint64_t v) { return ReportField{name, K::Integer, {}, v, 0.0}; };
    const auto real = [](const char* name, double v) { return ReportField{name, K::Real, {}, 0, v}; };
    std::vector<ReportField> fields{text("input", r.file),
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
            real("seconds", r.seconds),
            real("seconds_slabs", r.secondsSlabs),
            real("seconds_final", r.secondsFinal),
            real("peak_rss_mb", r.peakRssMb),
            real("max_error_accepted", r.maxErrorAccepted)};
    // A LOD chain: each level's own counts, after the run's fields (which describe the last level).
    for (size_t i = 0; i < r.levels.size(); ++i) {
        const LevelReport& l = r.levels[i];
        const std::string p = "lod" + std::to_string(i) + "_";
        fields.push_back({p + "ratio", K::Real, {}, 0, l.ratio});
        fields.push_back({p + "faces_target", K::Integer, {}, l.facesTarget, 0.0});
        fields.push_back({p + "faces_out", K::Integer, {}, l.facesOut, 0.0});
        fields.push_back({p + "verts_out", K::Integer, {}, l.vertsOut, 0.0});
        fields.push_back({p + "max_error_accepted", K::Real, {}, 0, l.maxErrorAccepted});
        fields.push_back({p + "seconds", K::Real, {}, 0, l.seconds});
    }
    return fields;
}

} // namespace vdb_isosimp
