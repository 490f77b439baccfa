"""MkDocs hook (``mkdocs.yml``: ``hooks``): every registered task's spec sheet on the Tasks page.

``docs/tasks.md`` holds the line :data:`MARKER`; this hook puts there one mkdocstrings block per
task module of :mod:`comat.tasks` (its module docstring, the spec sheet), in the order the tasks
are registered, so a new task's sheet appears with no edit of the page. Plug-in tasks (``COMAT_TASKS``)
are left out: their modules are not comat's.
"""

from __future__ import annotations

MARKER = "<!-- spec sheets of the registered tasks -->"
OPTIONS = "    options:\n      show_root_heading: true\n      members: false"


def spec_sheet_blocks() -> str:
    """The mkdocstrings blocks of the registered tasks' modules, in registration order."""
    from comat.tasks import TASKS

    modules = dict.fromkeys(e.logic.__module__ for e in TASKS.values() if e.logic.__module__.startswith("comat.tasks."))
    return "\n\n".join(f"::: {module}\n{OPTIONS}" for module in modules)


def on_page_markdown(markdown: str, **kwargs) -> str:
    """The page with :data:`MARKER` replaced by :func:`spec_sheet_blocks`."""
    return markdown.replace(MARKER, spec_sheet_blocks()) if MARKER in markdown else markdown
