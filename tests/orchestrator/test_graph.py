"""Direct-feedthrough graph, step order and algebraic loops (pure data)."""

from itertools import permutations

from hypothesis import given, settings
from hypothesis import strategies as st

from orchestrator.cosim.graph import feedthrough_edges, step_groups, strongly_connected
from orchestrator.scenario import Connection


def C(a, b):
    (s, sv), (t, tv) = a.split("."), b.split(".")
    return Connection(s, sv, t, tv)


def test_outputs_without_feedthrough_impose_no_order():
    # structure strain has no dependencies; the controller has a D path y -> u
    ft = {"plant": {"strain": set(), "acc": {"f"}}, "ctrl": {"u": {"y"}}}
    conns = [C("plant.strain", "ctrl.y"), C("ctrl.u", "plant.f")]
    edges = feedthrough_edges(conns, ft)
    assert [(c.source, c.target) for c in edges] == [("ctrl", "plant")]
    groups, loops = step_groups(["plant", "ctrl"], edges)
    assert groups == [("ctrl",), ("plant",)] and loops == []


def test_output_depending_only_on_unconnected_inputs_is_no_edge():
    ft = {"a": {"y": {"p"}}, "b": {"z": set()}}
    assert feedthrough_edges([C("a.y", "b.u")], ft) == []


def test_algebraic_loop_is_found_and_named():
    ft = {"plant": {"acc": {"f"}}, "ctrl": {"u": {"y"}}, "log": {}}
    conns = [C("plant.acc", "ctrl.y"), C("ctrl.u", "plant.f"), C("plant.acc", "log.x")]
    groups, loops = step_groups(["log", "plant", "ctrl"], feedthrough_edges(conns, ft))
    assert groups == [("plant", "ctrl"), ("log",)]
    assert len(loops) == 1
    assert loops[0].members == ("plant", "ctrl")
    assert loops[0].describe() == "plant.acc -> ctrl.y, ctrl.u -> plant.f"


def test_self_loop_is_a_loop():
    ft = {"g": {"y": {"u"}}}
    groups, loops = step_groups(["g"], feedthrough_edges([C("g.y", "g.u")], ft))
    assert loops and loops[0].describe() == "g.y -> g.u"


def test_topological_order_for_every_declaration_order():
    # chain a -> b -> c -> d with feedthrough everywhere, plus a -> d
    ft = {n: {"y": {"u", "v"}} for n in "abcd"}
    conns = [C("a.y", "b.u"), C("b.y", "c.u"), C("c.y", "d.u"), C("a.y", "d.v")]
    edges = feedthrough_edges(conns + [C("x.y", "a.u")], {**ft, "x": {"y": set()}})
    for order in permutations("abcdx"):
        groups, loops = step_groups(list(order), edges)
        flat = [g[0] for g in groups]
        assert not loops
        assert flat.index("a") < flat.index("b") < flat.index("c") < flat.index("d")


def test_tarjan_components():
    comps = strongly_connected(list("abcde"), [("a", "b"), ("b", "a"), ("b", "c"),
                                               ("c", "d"), ("d", "c"), ("e", "e")])
    assert sorted(comps) == [("a", "b"), ("c", "d"), ("e",)]


def reference_order(instances, pairs):
    """The step order by its definition: repeatedly the first ready component in
    scenario order (the quadratic loop the module used before; the benchmark
    ``benchmarks/bench_scenario_checks.py`` times it against the module)."""
    comps = strongly_connected(list(instances), pairs)
    rank = {n: i for i, n in enumerate(instances)}
    comp_of = {n: ci for ci, comp in enumerate(comps) for n in comp}
    preds = {ci: set() for ci in range(len(comps))}
    for a, b in pairs:
        if comp_of[a] != comp_of[b]:
            preds[comp_of[b]].add(comp_of[a])
    done, groups = set(), []
    while len(groups) < len(comps):
        ready = [ci for ci in preds if ci not in done and preds[ci] <= done]
        ci = min(ready, key=lambda i: rank[comps[i][0]])
        done.add(ci)
        groups.append(comps[ci])
    return groups


@settings(max_examples=300, deadline=None)
@given(n=st.integers(1, 9), data=st.data())
def test_property_step_order_is_the_first_ready_group_in_scenario_order(n, data):
    names = [f"i{k}" for k in range(n)]
    pairs = data.draw(st.lists(st.tuples(st.sampled_from(names), st.sampled_from(names)),
                               max_size=3 * n))
    order = data.draw(st.permutations(names))
    edges = [C(f"{a}.y", f"{b}.u") for a, b in pairs]
    groups, _ = step_groups(order, edges)
    assert groups == reference_order(order, pairs)

