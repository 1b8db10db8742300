#!/usr/bin/env bash
# The layout's rules, checked on the source tree (run by ctest as structure.layout):
#  1. programs (apps/), the Python module (python/), examples (examples/), the converter (convert/) and
#     the evaluation library (eval/) include no header of the library's internals (src/): only the
#     public headers (include/vdb_isosimp/) and their own;
#  2. inside the library, includes flow one way between the layers, include/ <- core <- vdb <- io <-
#     pipeline <- mpi, and no module (a .h/.cpp pair) reaches itself through its includes;
#  3. the library's messages name no command-line flag (a library caller has none; the programs add them).
# Prints each violation as FILE: what, and exits 1 if there is one.
set -euo pipefail
cd "$(dirname "$0")/.."
exec /usr/bin/python3 - <<'PY'
import os, re, sys

INCLUDE = re.compile(r'^\s*#\s*include\s*"([^"]+)"', re.M)
LAYERS = ["core", "vdb", "io", "pipeline", "mpi"]  # each may include the ones before it
problems = []

def includes(path):
    with open(path, encoding="utf-8", errors="replace") as f:
        return INCLUDE.findall(f.read())

def sources(top):
    for d, _, files in os.walk(top):
        for name in sorted(files):
            if name.endswith((".h", ".hpp", ".cpp", ".cc")):
                yield os.path.join(d, name)

# Headers of the internals, by the names an include could use.
internal = set()
for p in sources("src"):
    rel = os.path.relpath(p, "src")
    internal.add(rel)
    internal.add(os.path.basename(p))

# 1. Outside the library: public headers only.
for top in ["apps", "python", "examples", "convert", "eval"]:
    for p in sources(top):
        own = os.path.dirname(p)
        for inc in includes(p):
            if os.path.exists(os.path.join(own, inc)) or os.path.exists(os.path.join(top, inc)):
                continue  # its own folder's header
            if inc in internal or inc.split("/")[0] in LAYERS:
                problems.append(f"{p}: includes \"{inc}\", a header of the library's internals (src/)")

# 2. Inside the library: layer order and module circles.
def layer(rel):
    return rel.split("/")[0]

graph = {}
for p in sources("src"):
    rel = os.path.relpath(p, "src")
    module = os.path.splitext(rel)[0]
    graph.setdefault(module, set())
    for inc in includes(p):
        if inc.startswith("vdb_isosimp/"):
            continue  # the public headers sit below every layer
        if not os.path.exists(os.path.join("src", inc)):
            problems.append(f"{p}: includes \"{inc}\", which is not under src/ as written (use LAYER/NAME.h)")
            continue
        target = os.path.splitext(inc)[0]
        if LAYERS.index(layer(inc)) > LAYERS.index(layer(rel)):
            problems.append(f"{p}: the {layer(rel)} layer includes \"{inc}\" from the {layer(inc)} layer above it")
        if target != module:
            graph[module].add(target)

state = {}
def visit(m, stack):
    state[m] = 1
    stack.append(m)
    for n in sorted(graph.get(m, ())):
        if state.get(n) == 1:
            cycle = stack[stack.index(n):] + [n]
            problems.append("include circle: " + " -> ".join(cycle))
        elif n not in state:
            visit(n, stack)
    stack.pop()
    state[m] = 2
for m in sorted(graph):
    if m not in state:
        visit(m, [])

# 3. No command-line flag in a string literal of the library.
FLAG = re.compile(r'"(?:[^"\\\n]|\\.)*?(?<![\w-])--[a-z][a-z-]*')
for top in ["src", "include"]:
    for p in sources(top):
        with open(p, encoding="utf-8", errors="replace") as f:
            for n, line in enumerate(f, 1):
                code = line.split("//")[0]
                if FLAG.search(code):
                    problems.append(f"{p}:{n}: a command-line flag in a library message")

for p in problems:
    print(p)
if problems:
    sys.exit(1)
print(f"structure: {len(graph)} library modules, one-way includes, no internals outside src/")
PY
