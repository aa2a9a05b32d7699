"""The direct-feedthrough graph: step order and algebraic loops.

An edge ``A -> B`` is a connection from an output of A that depends directly (FMI
ModelStructure ``dependencies``) on a connected input of A.  Under Gauss–Seidel, B must
step after A in a tick, because B needs the value A computes from its inputs of that
tick.  A connection from an output without feedthrough imposes no order: its value at a
communication point is known before the source steps.

Cycles of such edges are algebraic loops.  This module is pure data: instance names,
connections and dependency sets in, an ordered list of step groups out.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

__all__ = [
    "AlgebraicLoopError",
    "Loop",
    "describe_cycle",
    "feedthrough_edges",
    "init_order",
    "step_groups",
    "strongly_connected",
]


class AlgebraicLoopError(RuntimeError):
    """An algebraic loop that cannot be solved (or did not converge)."""


@dataclass(frozen=True)
class Loop:
    """An algebraic loop: instances that must be iterated together.

    Attributes
    ----------
    members : tuple of str
        Instances in the loop, in scenario order.
    cycle : tuple of str
        One cycle of the loop as connections ``"a.y -> b.u"``, in order.
    """

    members: tuple
    cycle: tuple

    def describe(self) -> str:
        """Return ``"a.y -> b.u, b.z -> a.v"``."""
        return ", ".join(self.cycle)


def feedthrough_edges(connections, feedthrough) -> list:
    """Return the connections that order their target after their source.

    Parameters
    ----------
    connections : sequence of Connection-like
        Objects with ``source``, ``source_var``, ``target``, ``target_var``.
    feedthrough : dict of str to dict of str to set of str
        For each instance, each output's direct input dependencies (input names).

    Returns
    -------
    list of Connection-like
        Those whose source output depends on at least one connected input of its source.
    """
    connected = {}
    for c in connections:
        connected.setdefault(c.target, set()).add(c.target_var)
    edges = []
    for c in connections:
        deps = feedthrough.get(c.source, {}).get(c.source_var, ())
        if connected.get(c.source, set()) & set(deps):
            edges.append(c)
    return edges


def strongly_connected(nodes, edges) -> list:
    """Return the strongly connected components (Tarjan), each a tuple in node order.

    Parameters
    ----------
    nodes : sequence of str
    edges : iterable of (str, str)

    Returns
    -------
    list of tuple of str
        Components in reverse topological order of the condensation.
    """
    succ = {n: [] for n in nodes}
    for a, b in edges:
        succ[a].append(b)
    rank = {n: i for i, n in enumerate(nodes)}
    index, low, on_stack, stack, comps = {}, {}, set(), [], []
    counter = [0]

    def visit(v):  # iterative Tarjan to avoid deep recursion
        work = [(v, iter(succ[v]))]
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        while work:
            node, it = work[-1]
            advanced = False
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(succ[w])))
                    advanced = True
                    break
                if w in on_stack:
                    low[node] = min(low[node], index[w])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == node:
                        break
                comps.append(tuple(sorted(comp, key=rank.__getitem__)))

    for n in nodes:
        if n not in index:
            visit(n)
    return comps


def describe_cycle(members, edges) -> tuple:
    """Return one cycle through `members` as ``"a.y -> b.u"`` strings.

    Parameters
    ----------
    members : sequence of str
        A strongly connected set of instances.
    edges : sequence of Connection-like
        Feedthrough edges (see :func:`feedthrough_edges`).
    """
    inside = set(members)
    out = {}
    for c in edges:
        if c.source in inside and c.target in inside:
            out.setdefault(c.source, []).append(c)
    start = members[0]
    path, seen, node = [], {}, start
    while node not in seen:  # walk until a node repeats: that closes a cycle
        seen[node] = len(path)
        c = out[node][0]
        path.append(c)
        node = c.target
    cyc = path[seen[node]:]
    return tuple(f"{c.source}.{c.source_var} -> {c.target}.{c.target_var}" for c in cyc)


def step_groups(instances, edges) -> tuple:
    """Order instances for Gauss–Seidel and find the algebraic loops.

    Parameters
    ----------
    instances : sequence of str
        Instance names in scenario order (ties keep this order).
    edges : sequence of Connection-like
        Feedthrough edges (see :func:`feedthrough_edges`).

    Returns
    -------
    groups : list of tuple of str
        Step groups in order; a group of more than one instance (or one with a
        self-loop) is an algebraic loop.
    loops : list of Loop
        The algebraic loops, in step order.
    """
    pairs = [(c.source, c.target) for c in edges]
    comps = strongly_connected(list(instances), pairs)
    rank = {n: i for i, n in enumerate(instances)}
    comp_of = {n: ci for ci, comp in enumerate(comps) for n in comp}
    succs = [set() for _ in comps]
    for a, b in pairs:
        if comp_of[a] != comp_of[b]:
            succs[comp_of[a]].add(comp_of[b])
    waiting = [0] * len(comps)   # predecessors not yet placed
    for nxt in succs:
        for cj in nxt:
            waiting[cj] += 1
    # Kahn's algorithm, ties by scenario order: a heap of the ready components keyed by
    # the scenario rank of their first member (linear in the graph, up to the heap's log)
    ready = [(rank[comps[ci][0]], ci) for ci in range(len(comps)) if not waiting[ci]]
    heapq.heapify(ready)
    groups = []
    while ready:
        _, ci = heapq.heappop(ready)
        groups.append(comps[ci])
        for cj in succs[ci]:
            waiting[cj] -= 1
            if not waiting[cj]:
                heapq.heappush(ready, (rank[comps[cj][0]], cj))
    self_loops = {a for a, b in pairs if a == b}
    loops = [
        Loop(g, describe_cycle(g, edges))
        for g in groups
        if len(g) > 1 or g[0] in self_loops
    ]
    return groups, loops


def init_order(instances, connections, feedthrough) -> list:
    """Order instances for initialisation: a source before the sinks whose outputs need it.

    A connection ``A.y -> B.u`` orders A before B when some output of B depends directly
    on ``u``; an input that only drives B's state does not, because B's initial outputs
    do not need it.  Cycles keep scenario order.

    Parameters
    ----------
    instances : sequence of str
    connections : sequence of Connection-like
    feedthrough : dict of str to dict of str to set of str
        Each instance's outputs' direct input dependencies.

    Returns
    -------
    list of str
    """
    used = {n: set().union(*feedthrough.get(n, {}).values()) if feedthrough.get(n) else set()
            for n in instances}
    edges = [c for c in connections if c.target_var in used.get(c.target, set())
             and c.source != c.target]
    groups, _ = step_groups(instances, edges)
    return [m for g in groups for m in g]
