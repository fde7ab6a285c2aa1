"""A fake installed distribution that declares an entry point, for tests of plugin discovery."""

from pathlib import Path


def install_entry_point(tmp_path: Path, monkeypatch, module: str, source: str, name: str, attr: str,
                        group: str = "assocbench.associators") -> None:
    """Write ``module``.py with ``source`` and a ``<module>-1.0.dist-info`` declaring ``name =
    module:attr`` in ``group``, and put ``tmp_path`` on ``sys.path`` (as an installed package is)."""
    (tmp_path / f"{module}.py").write_text(source)
    dist = tmp_path / f"{module}-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {module.replace('_', '-')}\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text(f"[{group}]\n{name} = {module}:{attr}\n")
    monkeypatch.syspath_prepend(str(tmp_path))
