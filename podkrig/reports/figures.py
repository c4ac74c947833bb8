"""Matplotlib for report figures: the non-interactive Agg backend, imported only when drawing
(``matplotlib.pyplot`` takes ≈ 0.5 s to import on an idle core, more than the rest of a report
module; commands that draw nothing do not pay it)."""


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend (unless the user already chose one)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt
