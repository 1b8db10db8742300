#include "vdb_isosimp/vdb_isosimp.h"

#include <algorithm>

namespace vdb_isosimp {

std::string stopReason(uint64_t facesOut, uint64_t facesTarget, bool boundHeld)
{
    // A closed surface's face count is even, so a small odd target is missed by one.
    if (facesTarget > 0 && facesOut <= facesTarget + std::max<uint64_t>(2, facesTarget / 100)) return "target";
    return boundHeld ? "error bound" : "topology";
}

std::vector<ReportField> reportFields(const Report& r, const Options& o)
{
    using K = ReportField::Kind;
    const auto text = [](const char* name, const std::string& v) { return ReportField{name, K::Text, v, 0, 0.0, {}}; };
    const auto integer = [](const char* name, uint64_t v) { return ReportField{name, K::Integer, {}, v, 0.0, {}}; };
    const auto real = [](const char* name, double v) { return ReportField{name, K::Real, {}, 0, v, {}}; };
    const auto reals = [](const char* name, const std::vector<double>& v) { return ReportField{name, K::Reals, {}, 0, 0.0, v}; };
    const auto column = [&r](auto&& f) {
        std::vector<double> v;
        for (const Report::TreeNode& n : r.tree) v.push_back(f(n));
        return v;
    };
    std::vector<ReportField> fields{text("input", r.file),
            text("grid", r.grid),
            text("value_type", r.valueType),
            text("grid_class", r.gridClass),
            real("iso", r.iso),
            real("ratio", r.ratio),
            integer("batch", o.batchFaces),
            integer("blocks", r.blocks),
            integer("blocks_per_slab", o.blocksPerSlab),
            integer("slabs", r.slabs),
            integer("faces_full", r.facesFull),
            integer("faces_target", r.facesTarget),
            integer("faces_out", r.facesOut),
            integer("verts_out", r.vertsOut),
            integer("decimations", r.decimations),
            integer("max_intermediate_faces", r.maxIntermediateFaces),
            integer("max_uncontractible_faces", r.maxUncontractibleFaces),
            text("stopped_by", r.stoppedBy),
            integer("components_dropped", r.componentsDropped),
            integer("components_pruned", r.componentsPruned),
            integer("faces_retired", r.facesRetired),
            integer("queue_pops", r.queuePops),
            integer("queue_dead", r.queueDead),
            integer("queue_stale", r.queueStale),
            integer("collapse_attempts", r.collapseAttempts),
            integer("collapses", r.collapses),
            real("seconds", r.seconds),
            real("seconds_slabs", r.secondsSlabs),
            real("seconds_final", r.secondsFinal),
            real("seconds_final_parallel", r.secondsFinalParallel),
            real("seconds_count", r.secondsCount),
            integer("count_stride", r.countStride),
            real("count_margin", r.countMargin),
            real("seconds_layout", r.secondsLayout),
            real("seconds_open", r.secondsOpen),
            real("seconds_check", r.secondsCheck),
            real("seconds_topology", r.secondsTopology),
            real("seconds_blocks", r.secondsBlocks),
            real("seconds_blocks_merge", r.secondsBlocksMerge),
            integer("block_merge_rounds", r.blockMergeRounds),
            real("seconds_cut", r.secondsCut),
            real("seconds_samplers", r.secondsSamplers),
            real("peak_rss_mb", r.peakRssMb),
            real("max_error_accepted", r.maxErrorAccepted),
            integer("ranks", r.ranks),
            reals("rank_seconds", r.rankSeconds),
            reals("rank_peak_rss_mb", r.rankPeakRssMb),
            reals("rank_bytes_sent", r.rankBytesSent),
            reals("rank_setup_cpu_seconds", r.rankSetupCpuSeconds),
            reals("tree_first_slab", column([](const Report::TreeNode& n) { return double(n.firstSlab); })),
            reals("tree_end_slab", column([](const Report::TreeNode& n) { return double(n.endSlab); })),
            reals("tree_seconds", column([](const Report::TreeNode& n) { return n.seconds; }))};
    // A LOD chain: each level's own counts, after the run's fields (which describe the last level).
    for (size_t i = 0; i < r.levels.size(); ++i) {
        const LevelReport& l = r.levels[i];
        const std::string p = "lod" + std::to_string(i) + "_";
        fields.push_back(real((p + "ratio").c_str(), l.ratio));
        fields.push_back(integer((p + "faces_target").c_str(), l.facesTarget));
        fields.push_back(integer((p + "faces_out").c_str(), l.facesOut));
        fields.push_back(integer((p + "verts_out").c_str(), l.vertsOut));
        fields.push_back(text((p + "stopped_by").c_str(), l.stoppedBy));
        fields.push_back(real((p + "max_error_accepted").c_str(), l.maxErrorAccepted));
        fields.push_back(real((p + "seconds").c_str(), l.seconds));
    }
    return fields;
}

} // namespace vdb_isosimp
