#!/usr/bin/python3
"""benchmarks/scale_model.py against schedules worked out by hand (docs/scale.md reads its numbers).

A report of 4 slabs and 3 joins: the tree [0, 4) -> [0, 2) + [2, 4), each of two slabs.
  * Threads (one process): slabs start in order on the first free thread, the thread that finishes a
    node's second child joins it at once, a thread whose node waits takes the next slab.
  * Ranks of one thread: rank shares in proportion to slabs, a node on one rank is the sum of its
    nodes, on more ranks max(left, right + transfer) + its join.
  * The bound of any schedule: every node but the root spread evenly, then the root; the longest
    chain of a slab and its joins; every slab spread evenly, then the cheapest joins above a slab:
    whichever is longest.
Usage: test_scale_model.py path/to/benchmarks/scale_model.py
"""
import importlib.util
import sys
import unittest

spec = importlib.util.spec_from_file_location("scale_model", sys.argv.pop(1))
scale_model = importlib.util.module_from_spec(spec)
spec.loader.exec_module(scale_model)


def report(slab_seconds, join_seconds):
    """A -j 1 report of a 4-slab tree; joins in the order [0, 2), [2, 4), [0, 4)."""
    nodes = [(i, i + 1) for i in range(4)] + [(0, 2), (2, 4), (0, 4)]
    seconds = list(slab_seconds) + list(join_seconds)
    total = sum(seconds)
    return {
        "tree_first_slab": [l for l, _ in nodes], "tree_end_slab": [r for _, r in nodes], "tree_seconds": seconds,
        "slabs": 4, "faces_out": 0, "seconds": total + 1.0, "seconds_slabs": total, "seconds_final": 0.25,
    }


def nodes_of(rep):
    return {(l, r): s for l, r, s in zip(rep["tree_first_slab"], rep["tree_end_slab"], rep["tree_seconds"])}


class ThreadModel(unittest.TestCase):
    def test_one_thread_is_the_sum(self):
        rep = report([1, 1, 1, 1], [0.5, 0.5, 0.5])
        self.assertAlmostEqual(scale_model.threads_tree(nodes_of(rep), 4, 1)[0], 5.5)

    def test_two_threads_equal_slabs(self):
        # t=1: slabs 0 and 1 done; the second joins [0, 2) until 1.5, the first takes slab 2 (until 2);
        # slab 3 from 1.5 to 2.5, then [2, 4) until 3.0 and the root until 3.5.
        rep = report([1, 1, 1, 1], [0.5, 0.5, 0.5])
        t, path = scale_model.threads_tree(nodes_of(rep), 4, 2)
        self.assertAlmostEqual(t, 3.5)
        self.assertEqual(len(path), 3)  # slab 3, then [2, 4), then the root
        self.assertTrue(path[0].startswith("slab 3"))

    def test_two_threads_one_long_slab(self):
        # Slab 0 takes 3 s; the other thread makes slabs 1, 2, 3 meanwhile (until 3), then [0, 2) and
        # [2, 4) run at once (3.0-3.5) and the root follows (until 4.0).
        rep = report([3, 1, 1, 1], [0.5, 0.5, 0.5])
        self.assertAlmostEqual(scale_model.threads_tree(nodes_of(rep), 4, 2)[0], 4.0)

    def test_more_threads_than_slabs(self):
        rep = report([1, 2, 1, 1], [0.5, 0.25, 0.5])
        self.assertAlmostEqual(scale_model.threads_tree(nodes_of(rep), 4, 64)[0], 3.0)


class ScheduleBound(unittest.TestCase):
    def test_work_bound(self):
        # Two workers: the six nodes below the root (5.0 s) take at least 2.5 s, then the root 0.5 s; the
        # threads' schedule (3.5 s) leaves 0.5 s to a better one.
        rep = report([1, 1, 1, 1], [0.5, 0.5, 0.5])
        self.assertAlmostEqual(scale_model.schedule_bound(nodes_of(rep), 4, 2), 3.0)

    def test_chain_bound(self):
        # Many workers: the longest chain, slab 1 (2 s), [0, 2) and the root, 3.0 s; the threads reach it.
        rep = report([1, 2, 1, 1], [0.5, 0.25, 0.5])
        self.assertAlmostEqual(scale_model.schedule_bound(nodes_of(rep), 4, 64), 3.0)
        # The long first slab of two workers: the bound and the threads' schedule agree (4.0 s).
        rep = report([3, 1, 1, 1], [0.5, 0.5, 0.5])
        self.assertAlmostEqual(scale_model.schedule_bound(nodes_of(rep), 4, 2), 4.0)


    def test_last_slab_bound(self):
        # Three workers, joins as dear as slabs: the slabs take at least 4/3 s, and whichever finishes
        # last has two joins above it (2 s): 3.33 s, above the other two bounds (6 s of nodes below the
        # root / 3 + 1 = 3; the longest chain 1 + 1 + 1 = 3).
        rep = report([1, 1, 1, 1], [1.0, 1.0, 1.0])
        self.assertAlmostEqual(scale_model.schedule_bound(nodes_of(rep), 4, 3), 4 / 3 + 2)
        # A dearer left join: the last slab may be a right one, whose joins cost 2 s (the longest chain,
        # 1 + 1.2 + 1, and 6.2 / 3 + 1 stay below).
        rep = report([1, 1, 1, 1], [1.2, 1.0, 1.0])
        self.assertAlmostEqual(scale_model.schedule_bound(nodes_of(rep), 4, 3), 4 / 3 + 2)


class RankModel(unittest.TestCase):
    def test_two_ranks(self):
        # Rank 0: slabs 0, 1 and [0, 2) = 4.5 s; rank 1: 2.5 s plus its transfer (no faces: 0); root 0.5.
        rep = report([3, 1, 1, 1], [0.5, 0.5, 0.5])
        setup, tree, final, rows, _, _ = scale_model.model(rep, rep["seconds"] + 0.5)
        self.assertAlmostEqual(tree, 7.5)
        self.assertAlmostEqual(final, 0.75)
        by_workers = {row[0]: row for row in rows}
        self.assertAlmostEqual(by_workers[2][1], setup + 5.0 + final)
        self.assertAlmostEqual(by_workers[2][3], setup + 4.0 + final)  # threads, as above
        self.assertAlmostEqual(by_workers[1][2], 1.0)
        self.assertAlmostEqual(by_workers[1][6], 1.0)  # one worker: the bound is the serial run
        self.assertAlmostEqual(by_workers[2][5], setup + 4.0 + final)

    def test_final_scan_divided_among_threads(self):
        # 0.2 s of the final pass runs on all threads (the zero-area scan, the mesh's collection): two
        # threads make it 0.1 s, four 0.05 s; ranks of one thread pay it whole, and one worker is the serial run either way.
        rep = report([3, 1, 1, 1], [0.5, 0.5, 0.5])
        rep["seconds_final_parallel"] = 0.2
        setup, tree, final, rows, _, _ = scale_model.model(rep, rep["seconds"] + 0.5)
        by_workers = {row[0]: row for row in rows}
        self.assertAlmostEqual(by_workers[2][1], setup + 5.0 + final)
        self.assertAlmostEqual(by_workers[2][3], setup + 4.0 + final - 0.1)
        self.assertAlmostEqual(by_workers[2][5], setup + 4.0 + final - 0.1)
        self.assertAlmostEqual(by_workers[4][3], setup + scale_model.threads_tree(nodes_of(rep), 4, 4)[0] + final - 0.15)
        self.assertAlmostEqual(by_workers[1][2], 1.0)
        self.assertAlmostEqual(by_workers[1][4], 1.0)

    def test_measured_setup_of_ranks(self):
        # The one process's set-up (0.75 s: seconds less slabs and final) at W = 1 and a rank's measured
        # 0.3 s at W = 4 fit S(W) = 0.15 + 0.6 / W: 4 ranks pay 0.3 s, 2 ranks 0.45 s, one worker the serial run.
        rep = report([3, 1, 1, 1], [0.5, 0.5, 0.5])
        setup, tree, final, rows, _, line = scale_model.model(rep, rep["seconds"] + 0.5, setup_points=[(4, 0.3)])
        self.assertAlmostEqual(setup, 0.75)
        self.assertAlmostEqual(line[0], 0.15)
        self.assertAlmostEqual(line[1], 0.6)
        by_workers = {row[0]: row for row in rows}
        self.assertAlmostEqual(by_workers[4][1], 0.3 + 4.0 + final)  # [0, 2) 3 + 0.5, the root 0.5 above it
        self.assertAlmostEqual(by_workers[2][1], 0.45 + 5.0 + final)  # each rank two slabs and their join
        self.assertAlmostEqual(by_workers[1][2], 1.0)
        # The threads' model does not use it.
        self.assertAlmostEqual(by_workers[2][3], setup + 4.0 + final)

    def test_leaf_walk_shared_among_ranks(self):
        # 1 s of checking, CHECK_SERIAL of it the topology every rank walks: of the rest, the leaf
        # records, a rank walks its part and its kept leaves' (2/R): all of it on 2 ranks, half on 4.
        rep = report([3, 1, 1, 1], [0.5, 0.5, 0.5])
        rep["seconds_check"] = 1.0
        rep["seconds_blocks"] = 0.4
        setup, tree, final, rows, _, _ = scale_model.model(rep, rep["seconds"] + 0.5)
        by_workers = {row[0]: row for row in rows}
        shared = 1.0 - scale_model.CHECK_SERIAL
        self.assertAlmostEqual(by_workers[2][1], setup + 5.0 + final)
        self.assertAlmostEqual(by_workers[4][1], setup - shared / 2 + 4.0 + final)
        self.assertAlmostEqual(by_workers[1][2], 1.0)


class MixedModel(unittest.TestCase):
    def test_a_subtree_on_threads(self):
        # Slabs [2, 4) alone on two threads: both slabs at once (1 s), then [2, 4) (0.5 s).
        rep = report([3, 1, 1, 1], [0.5, 0.5, 0.5])
        self.assertAlmostEqual(scale_model.threads_tree(nodes_of(rep), 4, 2, first=2)[0], 1.5)
        self.assertAlmostEqual(scale_model.threads_tree(nodes_of(rep), 1, 2, first=0)[0], 3.0)  # one slab

    def test_two_ranks_of_two_threads(self):
        # Four workers as two ranks of two threads: rank 0 makes slabs 0 (3 s) and 1 at once, then
        # [0, 2): 3.5 s; rank 1 [2, 4) in 1.5 s; the root 0.5 s: 4.0 s of tree. A quarter of the
        # final pass's 0.2 s parallel part is left on each rank's two threads: 0.1 s of it.
        rep = report([3, 1, 1, 1], [0.5, 0.5, 0.5])
        rep["seconds_final_parallel"] = 0.2
        saved = scale_model.RANK_THREADS
        scale_model.RANK_THREADS = 2
        try:
            setup, tree, final, rows, _, _ = scale_model.model(rep, rep["seconds"] + 0.5)
        finally:
            scale_model.RANK_THREADS = saved
        by_workers = {row[0]: row for row in rows}
        self.assertAlmostEqual(by_workers[4][7], setup + 4.0 + final - 0.1)
        self.assertAlmostEqual(by_workers[2][7], by_workers[2][3])  # fewer workers: one process of threads


class Messages(unittest.TestCase):
    def test_each_rank_sends_its_top_node(self):
        # 91 slabs on 16 ranks, as pipeline/slabs.cpp shares them out: the root's right half [46, 91) goes
        # to ranks 8-15 (16 * 46 / 91 = 8.1), whose first sends it to rank 0; [0, 46) on ranks 0-7 gives its
        # right half [23, 46) to rank 4 (8 * 23 / 46); [46, 91) on ranks 8-15 gives [69, 91) to rank 12
        # (8 * 23 / 45 = 4.1). Fifteen messages, every slab's rank but rank 0 sending once.
        sent = scale_model.rank_top_nodes(91, 16)
        self.assertEqual(sorted(sent), list(range(1, 16)))
        self.assertEqual(sent[8], (46, 91))
        self.assertEqual(sent[4], (23, 46))
        self.assertEqual(sent[12], (69, 91))
        self.assertEqual(scale_model.rank_top_nodes(4, 2), {1: (2, 4)})

    def test_line_through_the_messages(self):
        # Messages of 2 MB plus 0.5 MB a slab come back as that line; ranks the report leaves out are skipped.
        sent = scale_model.rank_top_nodes(91, 16)
        measured = [0.0] * 16
        for k, (l, r) in sent.items():
            measured[k] = 2e6 + 0.5e6 * (r - l)
        fixed, per_slab, points = scale_model.message_fit({"slabs": 91, "ranks": 16, "rank_bytes_sent": measured})
        self.assertAlmostEqual(fixed / 1e6, 2.0)
        self.assertAlmostEqual(per_slab / 1e6, 0.5)
        self.assertEqual(len(points), 15)
        _, _, points = scale_model.message_fit({"slabs": 91, "ranks": 16, "rank_bytes_sent": measured[:9]})
        self.assertEqual(len(points), 8)

    def test_transfer_on_the_ranks_path(self):
        # Two ranks: rank 1 makes [2, 4) (1 + 1 + 0.5 s) and sends it, 1e9 + 1e9 * 2 bytes at 1 GB/s = 3 s,
        # while rank 0 makes [0, 2) (3 + 1 + 0.5 s): the root waits for max(4.5, 2.5 + 3) = 5.5 s, then 0.5 s.
        rep = report([3, 1, 1, 1], [0.5, 0.5, 0.5])
        setup, tree, final, rows, _, _ = scale_model.model(rep, rep["seconds"] + 0.5, messages=(1e9, 1e9))
        by_workers = {row[0]: row for row in rows}
        self.assertAlmostEqual(by_workers[2][1], setup + 6.0 + final)


class BestOfRuns(unittest.TestCase):
    def test_each_node_and_part_its_least(self):
        # Two runs of the same tree, each slow on other nodes and parts: the best has every node's and part's
        # least seconds, the set-up no field names (seconds less the named parts) and the write (wall less
        # seconds) each their least too.
        import json
        import os
        import tempfile
        a = report([2, 1, 1, 1], [0.5, 0.9, 0.5])
        b = report([1, 1, 3, 1], [0.7, 0.5, 0.5])
        a["seconds_final"], b["seconds_final"] = 0.25, 0.75
        b["seconds"] += 1.0  # unnamed set-up: a's 1.0 - 0.25 = 0.75 s, b's 2.0 - 0.75 = 1.25 s
        with tempfile.TemporaryDirectory() as d:
            paths = []
            for name, rep in (("a", a), ("b", b)):
                paths.append(os.path.join(d, name + ".json"))
                with open(paths[-1], "w") as f:
                    json.dump(rep, f)
            best, wall = scale_model.best_of_runs(paths, [a["seconds"] + 0.3, b["seconds"] + 0.2])
        nodes = nodes_of(best)
        self.assertEqual([nodes[(i, i + 1)] for i in range(4)], [1, 1, 1, 1])
        self.assertEqual([nodes[k] for k in ((0, 2), (2, 4), (0, 4))], [0.5, 0.5, 0.5])
        self.assertAlmostEqual(best["seconds_slabs"], 5.5)
        self.assertAlmostEqual(best["seconds_final"], 0.25)
        self.assertAlmostEqual(best["seconds"], 0.75 + 5.5 + 0.25)
        self.assertAlmostEqual(wall, best["seconds"] + 0.2)


if __name__ == "__main__":
    unittest.main(verbosity=2)
