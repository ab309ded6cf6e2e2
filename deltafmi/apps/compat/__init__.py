"""FMI compatibility information (the successor of the FMI Cross-Check): deltafmi's FMUs with
reference results in the published layout, and the results of importing others' FMUs.

- :mod:`.layout`: where files go in the tree; :mod:`.files`: ``X_ref.opt`` and the CSV rules;
- :mod:`.cases`: what each packaged model runs; :mod:`.run`: one FMU through the master, inputs
  replayed from a table;
- :mod:`.export`: ``deltafmi compat DIR``; :mod:`.importing`: ``deltafmi compat import FOLDER``;
  :mod:`.compare`: the check behind ``passed``.
"""
from .export import write_tree
from .importing import ImportResult, import_tree

__all__ = ["write_tree", "import_tree", "ImportResult"]
