"""``edgetruth methods``: the registered edge-localisation methods (built-in and plug-ins)."""
from __future__ import annotations

from edgetruth import locate
from edgetruth.cli import add_plugin_option


def register(sub) -> None:
    p = sub.add_parser("methods", help="list the method ids (built-in and plug-ins)",
                       description="One line per method: id, family, the seed study's name, summary.")
    add_plugin_option(p)
    p.set_defaults(handler=run)


def run(args) -> int:
    for m in locate.METHODS.values():
        print(f"{m.id:26s} {m.family:10s} {m.label:24s} {m.summary}")
    return 0
