"""The public API is typed: every parameter and return is annotated."""

import importlib
import importlib.resources
import inspect

import pytest

PACKAGES = ["allocation", "thrusters", "ocp", "adcs_common", "adcs.bench",
            "adcs.report", "adcs.sweep", "adcs.basilisk"]


def public_functions(pkg):
    mod = importlib.import_module(pkg)
    for name in getattr(mod, "__all__", []):
        obj = getattr(mod, name, None)
        if inspect.isfunction(obj):
            yield name, obj
        elif inspect.isclass(obj):
            for attr, fn in vars(obj).items():
                if inspect.isfunction(fn) and (not attr.startswith("_")
                                               or attr == "__init__"):
                    yield f"{name}.{attr}", fn


@pytest.mark.parametrize("pkg", PACKAGES)
def test_public_api_is_annotated(pkg):
    missing = []
    for name, fn in public_functions(pkg):
        sig = inspect.signature(inspect.unwrap(fn))
        for p in sig.parameters.values():
            if p.name in ("self", "cls") or p.kind in (
                    p.VAR_POSITIONAL, p.VAR_KEYWORD):
                continue
            if p.annotation is inspect.Parameter.empty:
                missing.append(f"{name}({p.name})")
        if (sig.return_annotation is inspect.Signature.empty
                and not name.endswith("__init__")):
            missing.append(f"{name} -> ?")
    assert not missing, missing
    assert (importlib.resources.files(pkg.split(".")[0]) / "py.typed"
            ).is_file()
