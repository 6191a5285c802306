"""Connection-graph analysis: algebraic loops, feedthrough propagation order, Gauss-Seidel order.

Terms: a connection ``a.y -> b.u`` links an output to an input. An output has direct
feedthrough from the inputs it depends on at the same instant (the model description's
``ModelStructure/Outputs`` dependencies; undeclared means all inputs). An algebraic loop
is a cycle of connections and feedthrough dependencies, none of them ``delayed``: it
has no well-defined value at a communication point, so it is reported, not broken.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from orchestration.master.unit import UnitDescription

Port = tuple[str, str]  # (unit, variable)


@dataclass(frozen=True)
class Link:
    """A resolved connection between two ports."""

    source: Port
    target: Port
    delayed: bool = False


class AlgebraicLoopError(ValueError):
    """A cycle of direct-feedthrough connections; ``cycle`` lists the ports around it."""

    def __init__(self, cycle: list[Port]) -> None:
        self.cycle = cycle
        path = " -> ".join(f"{u}.{v}" for u, v in cycle)
        super().__init__(
            f"algebraic loop (direct feedthrough all the way round, no delay): {path}. "
            "Mark one connection 'delayed: true' or use units whose outputs do not depend "
            "directly on those inputs."
        )


def _driven_inputs(links: Sequence[Link]) -> dict[Port, Port]:
    """target port -> source port, for links that propagate within a communication point."""
    return {link.target: link.source for link in links if not link.delayed}


def feedthrough_inputs(desc: Mapping[str, UnitDescription], links: Sequence[Link], port: Port) -> list[Port]:
    """Connected, non-delayed inputs the output ``port`` depends on directly."""
    driven = _driven_inputs(links)
    unit, name = port
    return [(unit, i) for i in desc[unit].feedthrough(name) if (unit, i) in driven]


def propagation_order(desc: Mapping[str, UnitDescription], links: Sequence[Link]) -> list[list[Port]]:
    """Outputs to re-evaluate after a step, in levels: each level only needs earlier ones.

    Only outputs that depend directly on a connected input are listed. Raises
    AlgebraicLoopError if they form a cycle.
    """
    driven = _driven_inputs(links)
    ft = {}
    for unit, d in desc.items():
        for out in d.outputs():
            port = (unit, out.name)
            inputs = feedthrough_inputs(desc, links, port)
            if inputs:
                ft[port] = [driven[i] for i in inputs]
    # Levels by longest path; a cycle is an algebraic loop.
    level: dict[Port, int] = {}
    state: dict[Port, int] = {}

    def visit(port: Port, stack: list[Port]) -> int:
        if state.get(port) == 2:
            return level[port]
        if state.get(port) == 1:
            start = stack.index(port)
            cycle = [*stack[start:], port]
            raise AlgebraicLoopError(_expand(cycle, desc, links))
        state[port] = 1
        stack.append(port)
        lv = 0
        for src in ft.get(port, []):
            if src in ft:
                lv = max(lv, visit(src, stack) + 1)
        stack.pop()
        state[port] = 2
        level[port] = lv
        return lv

    for port in ft:
        visit(port, [])
    depth = max(level.values(), default=-1) + 1
    return [[p for p in ft if level[p] == k] for k in range(depth)]


def _expand(cycle: list[Port], desc: Mapping[str, UnitDescription], links: Sequence[Link]) -> list[Port]:
    """Cycle of outputs (each depending on the next) -> the ports along the signal flow."""
    flow = cycle[::-1]
    out: list[Port] = [flow[0]]
    for src, dst in itertools.pairwise(flow):
        for link in links:
            if (
                link.source == src
                and not link.delayed
                and link.target[0] == dst[0]
                and link.target[1] in desc[dst[0]].feedthrough(dst[1])
            ):
                out.append(link.target)
                break
        out.append(dst)
    return out


def gauss_seidel_order(desc: Mapping[str, UnitDescription], links: Sequence[Link]) -> list[str]:
    """Order in which Gauss-Seidel steps the units.

    A unit steps after the units whose outputs it reads. Inside a feedback loop the edges
    from outputs without direct feedthrough (states, fresh right after their unit steps)
    are kept and those from feedthrough outputs are released first; remaining ties go by
    declaration order.
    """
    names = list(desc)
    edges: dict[str, set[str]] = {n: set() for n in names}  # unit -> units it reads from
    strong: dict[str, set[str]] = {n: set() for n in names}
    for link in links:
        if link.delayed or link.source[0] == link.target[0]:
            continue
        src_unit, dst_unit = link.source[0], link.target[0]
        edges[dst_unit].add(src_unit)
        if not feedthrough_inputs(desc, links, link.source):
            strong[dst_unit].add(src_unit)
    placed: list[str] = []
    remaining = list(names)
    while remaining:
        ready = [n for n in remaining if edges[n] <= set(placed)]
        if not ready:
            ready = [n for n in remaining if strong[n] <= set(placed)] or remaining
        placed.append(ready[0])
        remaining.remove(ready[0])
    return placed
