"""``ablate --dry-run``: the run's calls, tokens and cost, estimated (``ablation/estimate.py``) and shown."""

from __future__ import annotations

from rich.console import Console
from rich.markup import escape
from rich.table import Table


def _price(scenario, plugins):
    """The backend's ``cost`` function and why there is none (a missing key, a simulated pilot)."""
    from ..ablation.spending import backend_price
    from ..errors import SafeEmbodAIError

    try:
        price = backend_price(scenario, plugins)
    except SafeEmbodAIError as error:
        return None, f"the backend could not be built to ask its price: {error}"
    try:
        known = price(1000, 1000) is not None
    except Exception as error:  # a plugin's cost() that fails: no price, said plainly
        return None, f"backend {scenario.backend.use!r}: its price failed ({type(error).__name__}: {error})"
    if not known:
        return None, (f"backend {scenario.backend.use!r} knows no price (a simulated pilot, or a model litellm "
                      "has none for)")
    return price, ""


def show_estimate(scenario, plugins, resume_dir: str | None) -> None:
    from ..ablation.estimate import estimate
    from ..runs.runner import ScenarioRunner

    runner = ScenarioRunner(scenario, plugins, run_dir=resume_dir)
    try:
        specs = runner.specs()
        if resume_dir is not None:
            done = {r.spec.trial_id for r in runner.state.results() if r.outcome.value != "error"}
            specs = [s for s in specs if s.trial_id not in done]
    finally:
        runner.close()
    rows = estimate(scenario, plugins, specs)
    price, why = _price(scenario, plugins)
    table = Table(title=f"{escape(scenario.name)}: {len(specs)} trials to run, estimated (nothing was sent)",
                  box=None, padding=(0, 1, 0, 0), pad_edge=False, header_style="bold underline")
    for column in ("env", "arm", "trials", "calls min", "budget", "max", "prompt tok/call", "answer tok/call"):
        table.add_column(column, justify="left" if column in ("env", "arm") else "right")
    for row in rows:
        table.add_row(escape(row.environment), escape(row.arm), str(row.trials), f"{row.calls_min:,}",
                      f"{row.calls_budget:,}", f"{row.calls_max:,}", f"{row.prompt_tokens:,}",
                      f"{row.completion_tokens:,}")
    totals = {}
    for name in ("calls_min", "calls_budget", "calls_max"):
        calls = sum(getattr(r, name) for r in rows)
        prompt = sum(getattr(r, name) * r.prompt_tokens for r in rows)
        answer = sum(getattr(r, name) * r.completion_tokens for r in rows)
        totals[name] = (calls, prompt, answer, price(prompt, answer) if price else None)
    lines = []
    for name, words in (("calls_min", "one step per trial"), ("calls_budget", "every trial uses its step budget"),
                        ("calls_max", "and every answer but the last of a step is refused")):
        calls, prompt, answer, cost = totals[name]
        money = f", ${cost:,.2f}" if cost is not None else ""
        lines.append(f"{words}: {calls:,} calls, {prompt + answer:,} tokens{money}")
    table.caption = "\n".join([
        "tokens per call: one step per environment and arm run with the offline mock (the real prompt, counted "
        "as for gpt-4o); a model that writes more costs more",
        *lines, escape(why) if why else f"prices: the list price of backend {escape(scenario.backend.use)}'s model",
        "cached answers (--cache, a resume) are not paid again: the estimate counts every call"])
    Console(emoji=False).print(table)
