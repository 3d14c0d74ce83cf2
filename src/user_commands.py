"""setuptools commands that also link a package's user-facing console scripts into ``<prefix>/bin``.

ament_python puts every console script in ``<prefix>/lib/<pkg>/`` (where ``ros2 run`` looks; on no PATH).
After ``setup.py develop`` and ``setup.py install`` these add ``<prefix>/bin/<name> -> ../lib/<pkg>/<name>``
for the commands a user types; node executables stay in ``lib/<pkg>/`` only. See README.md.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from setuptools.command.develop import develop
from setuptools.command.install_scripts import install_scripts

__all__ = ["command_classes", "link_into_bin"]


def link_into_bin(script_dir: str, names: Iterable[str]) -> list[str]:
    """Link each script ``<prefix>/lib/<pkg>/<name>`` as ``<prefix>/bin/<name>``; returns the links made.

    Nothing is linked when ``script_dir`` is not a ``lib/<pkg>`` directory (scripts already in ``bin``).
    """
    lib_dir = Path(script_dir)
    if lib_dir.parent.name != "lib":
        return []
    bin_dir = lib_dir.parent.parent / "bin"
    bin_dir.mkdir(parents=True, exist_ok=True)
    made = []
    for name in names:
        link = bin_dir / name
        if link.is_symlink() or link.exists():
            link.unlink()
        link.symlink_to(os.path.relpath(lib_dir / name, bin_dir))
        made.append(str(link))
    return made


def command_classes(*names: str) -> dict[str, type]:
    """``cmdclass`` for ``setup()``: the console scripts ``names`` also go to ``<prefix>/bin``."""

    class Develop(develop):  # type: ignore[misc]
        def install_wrapper_scripts(self, dist: Any) -> Any:
            written = super().install_wrapper_scripts(dist)
            link_into_bin(self.script_dir, names)
            return written

    class InstallScripts(install_scripts):  # type: ignore[misc]
        def run(self) -> None:
            super().run()
            self.outfiles += link_into_bin(self.install_dir, names)

    return {"develop": Develop, "install_scripts": InstallScripts}
