"""Every top-level package has ``__version__``, from one source."""

import importlib
import tomllib
from importlib import metadata
from pathlib import Path

import pytest

from adcs_common import version as version_module

ROOT = Path(__file__).resolve().parents[2]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
#: the top-level packages pyproject.toml ships ("ocp*" -> "ocp")
PACKAGES = sorted({p.rstrip("*").rstrip(".") for p in PYPROJECT["tool"][
    "setuptools"]["packages"]["find"]["include"]})


def test_the_packages_are_the_ones_pyproject_lists():
    assert PACKAGES == ["adcs", "adcs_common", "allocation", "ocp",
                        "thrusters"]


@pytest.mark.parametrize("name", PACKAGES)
def test_each_package_has_the_distributions_version(name):
    package = importlib.import_module(name)
    assert package.__version__ == metadata.version("adcs-toolbox")
    assert package.__version__ == PYPROJECT["project"]["version"] == "0.1.0"


def test_the_version_has_one_source():
    from adcs.provenance import version as report_version

    versions = {importlib.import_module(n).__version__ for n in PACKAGES}
    assert versions == {version_module.version()} == {report_version()}


def test_without_installed_metadata_the_source_tree_tells(monkeypatch):
    def missing(name):
        raise metadata.PackageNotFoundError(name)

    monkeypatch.setattr(version_module.metadata, "version", missing)
    assert version_module.version() == PYPROJECT["project"]["version"]
    monkeypatch.setattr(version_module, "_source_version", lambda: None)
    assert version_module.version() == "unknown"
