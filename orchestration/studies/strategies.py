"""The control strategies of the studies, as scenario overrides of the paper's system.

| strategy | controller unit |
|---|---|
| ``passive-off`` | constant 0 A (``controller.mode=passive``) |
| ``passive-on`` | constant i_max |
| ``best-constant`` | the constant current chosen by the case study's sweep |
| ``sosm`` | the SOSM controller with the tuned gains (``scenarios/sosm_gains.yaml``) |
| ``sosm-fig15`` | SOSM, second gain set: own limit (2.5 A), release band s_release (not in the paper) |
| ``on-off`` | the ``SwitchingCurrentController`` FMU: i_max while the base moves away from 0, else 0 |
"""

from __future__ import annotations

from orchestration.project import PROJECT_DIR as PROJECT


def strategy_overrides(strategy: str, i_max: float, gains: dict[str, float] | None, best: float | None
                       ) -> tuple[str, ...]:
    """Scenario overrides that make a run follow a strategy (``gains``: the gain set of an SOSM strategy)."""
    if strategy in ("sosm", "sosm-fig15"):
        assert gains is not None
        own_limit = (f"controller.i_max={float(gains['i_max'])!r}",) if strategy == "sosm-fig15" else ()
        release = (f"controller.s_release={float(gains['s_release'])!r}",) if "s_release" in gains else ()
        return ("controller.mode=sosm", f"controller.lambda={gains['lambda']!r}", f"controller.rho={gains['rho']!r}",
                f"controller.zeta={gains['zeta']!r}", f"controller.theta={gains['theta']!r}", *own_limit, *release)
    if strategy == "on-off":
        return (f"units.controller.fmu={PROJECT / 'fmus' / 'SwitchingCurrentController.fmu'}",
                f"controller.i_high={i_max!r}", "controller.i_low=0.0")
    current = {"passive-off": 0.0, "passive-on": i_max, "best-constant": best}[strategy]
    return ("controller.mode=passive", f"controller.i_passive={current!r}")
