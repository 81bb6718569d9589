"""``edgetruth methods``: the registered edge-localisation methods."""
from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("methods", help="list the method ids")
    p.set_defaults(handler=run)


def run(args) -> int:
    import locate

    for m in locate.METHODS.values():
        print(f"{m.id:26s} {m.family:10s} {m.label:24s} {m.summary}")
    return 0
