"""parsel-view: slider pages and filmstrips of editing programs (docs/viewer.md).

``parsel view OUTDIR`` serves a page with one slider per program parameter; the page
evaluates the program and deforms the meshes itself, so a slider step never goes back
to the server. ``parsel render SHAPE PROGRAM -o strip.png`` draws the edited shape at
several parameter values. This module holds only the hook; the work is in submodules
imported when a command runs, so ``parsel --help`` stays fast.
"""

from __future__ import annotations

from parsel_core import hookimpl

__version__ = "0.1.0"


@hookimpl
def parsel_register_commands(subparsers):
    from parsel_view.commands import register

    register(subparsers)
