"""Names of a package imported on first use (PEP 562), so that ``import dopplertof``
and the command line's ``--help`` load neither NumPy nor the package's modules until
something asks for them.

A package's ``__init__`` lists what it exports, module by module, as its imports
would::

    __getattr__, __dir__, __all__ = lazy_exports(__name__, {
        ".preset": ("CameraPreset", "load_preset"),
    })

``tests/test_layers.py`` reads these tables as imports (the import graph keeps them).
"""

from __future__ import annotations

import importlib
import sys
import types


def lazy_exports(package: str, exports: dict) -> tuple:
    """(``__getattr__``, ``__dir__``, ``__all__``) of the package or module ``package``
    (its ``__name__``; ``__all__`` without the submodules):
    ``exports`` maps a submodule (relative, ``".preset"``) to the names it gives the
    package; a name that is the submodule itself (``".scene"`` giving ``"scene"``) is
    the module. (A function named as its module, ``render`` of ``.render``, cannot be
    lazy: importing the module anywhere would set the package's attribute to it.) The
    first access imports the submodule and keeps the name in the package, so later
    ones cost nothing."""
    where = {name: module for module, names in exports.items() for name in names}
    anchor = sys.modules[package].__package__  # (what the relative names start from)
    sys.modules[package]._LAZY_EXPORTS = where  # (name -> submodule, for the tests)

    def __getattr__(name: str):
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        loaded = importlib.import_module(module, anchor)
        value = loaded if module.lstrip(".") == name else getattr(loaded, name)
        if value is loaded and not isinstance(getattr(loaded, name, loaded), types.ModuleType):
            raise ImportError(f"{package}.{name}: the submodule and its own {name!r} share "
                              "the name; import that one eagerly (see dopplertof.lazy)")
        setattr(sys.modules[package], name, value)
        return value

    def __dir__():
        return sorted(set(vars(sys.modules[package])) | set(where))

    names = [name for name, module in where.items() if module.lstrip(".") != name]
    return __getattr__, __dir__, names
