"""The figures the docs print, each made by the code that measures it.

Every measured figure in README.md and docs/*.md sits in a generated block of its page (cogapp, ``cog``)::

    <!-- [[[cog from figures import method; cog.outl(method.margins_table()) ]]] -->
    | variant | gain margin | phase margin |
    ...
    <!-- [[[end]]] -->

The code between ``[[[cog`` and ``]]]`` runs and its output replaces the lines up to ``[[[end]]]``. A figure
that takes seconds is computed there and then; one that takes minutes (a population run, the accuracy table,
a timing) is a *measurement*: a function registered with :func:`figures.common.measurement`, whose result is
stored in ``docs/figures/data/<name>.json`` and printed by the block from there. ``python docs/regenerate.py``
writes the pages; ``--measure NAME`` measures again first; ``--check`` fails when a page differs from what the
code prints now (the default test suite runs it; the slow pass measures every deterministic measurement again
and checks the pages against the new results).

One module per page (``method.py`` for docs/method.md, ``readme.py`` for README.md, ...); ``common.py`` holds
the registry, the stored results and the formatting every page shares.
"""
