"""Loading a user's class from where they say it is: "path/to/file.py:Class",
"package.module:Class", or an installed package's entry point by name.

One loader for every registry (controllers: hil/controllers/registry.py; experiments:
hil/experiments/registry.py); each registry checks the class's contract itself.
"""

from hil.plugins.loading import PluginError, class_from_target, entry_point_target, target_of

__all__ = ["PluginError", "class_from_target", "entry_point_target", "target_of"]
