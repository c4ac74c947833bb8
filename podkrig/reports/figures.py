"""Matplotlib for report figures: the non-interactive Agg backend, imported only when drawing."""


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend (unless the user already chose one)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt
