"""The control strategies of the studies, as scenario overrides of the paper's system.

| strategy | controller unit |
|---|---|
| ``passive-off`` | constant 0 A (``controller.mode=passive``) |
| ``passive-on`` | constant i_max |
| ``best-constant`` | the constant current chosen by the case study's sweep |
| ``sosm`` | the SOSM controller with the tuned gains |
| ``on-off`` | the ``SwitchingCurrentController`` FMU: i_max while the base moves away from 0, else 0 |
"""

from __future__ import annotations

from orchestration.project import PROJECT_DIR as PROJECT


def strategy_overrides(strategy: str, i_max: float, gains: dict[str, float] | None, best: float | None
                       ) -> tuple[str, ...]:
    """Scenario overrides that make a run follow a strategy."""
    if strategy == "sosm":
        assert gains is not None
        return ("controller.mode=sosm", f"controller.lambda={gains['lambda']!r}", f"controller.rho={gains['rho']!r}",
                f"controller.zeta={gains['zeta']!r}", f"controller.theta={gains['theta']!r}")
    if strategy == "on-off":
        return (f"units.controller.fmu={PROJECT / 'fmus' / 'SwitchingCurrentController.fmu'}",
                f"controller.i_high={i_max!r}", "controller.i_low=0.0")
    current = {"passive-off": 0.0, "passive-on": i_max, "best-constant": best}[strategy]
    return ("controller.mode=passive", f"controller.i_passive={current!r}")
