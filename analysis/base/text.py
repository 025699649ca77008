"""How values read in tables and legends people look at (plain Python: a cached re-run loads no numpy)."""

__all__ = ["parameters"]


def parameters(params):
    """A parameter set as a table or a legend shows it: ``eps = 0.2, h = 0.05``, or ``defaults`` when empty.

    >>> parameters({"h": 0.05, "eps": 0.2}), parameters({})
    ('eps = 0.2, h = 0.05', 'defaults')
    """
    return ", ".join(f"{name} = {value:g}" for name, value in sorted(params.items())) or "defaults"
