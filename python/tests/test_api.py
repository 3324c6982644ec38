"""The package documents itself: help(mbsolve) renders, every public
function, class and method has a docstring, the type stubs name every
public name."""

import ast
import inspect
import pathlib
import pydoc

import mbsolve

PKG = pathlib.Path(mbsolve.__file__).parent


def public_members():
    for name in mbsolve.__all__:
        obj = getattr(mbsolve, name)
        if name.startswith("__"):
            continue
        yield name, obj
        if inspect.isclass(obj) and not issubclass(obj, BaseException):
            for m, v in vars(obj).items():
                if m.startswith("_") and m not in ("__init__", "__getitem__", "__len__"):
                    continue
                if callable(v) or isinstance(v, (property, classmethod, staticmethod)):
                    yield f"{name}.{m}", v


def test_every_public_function_has_a_docstring():
    missing = []
    for name, obj in public_members():
        f = obj.__func__ if isinstance(obj, (classmethod, staticmethod)) else obj
        doc = f.__doc__ if not isinstance(f, property) else f.fget.__doc__
        if name.endswith(".__init__"):
            continue  # the class's docstring documents construction
        if not (doc or "").strip():
            missing.append(name)
    assert not missing, missing


def test_help_renders():
    text = pydoc.render_doc(mbsolve, renderer=pydoc.plaintext)
    for word in ("Scenario", "Result", "PythonForce", "sweep", "Model", "load"):
        assert word in text
    assert "PythonForce" in pydoc.render_doc(mbsolve.PythonForce, renderer=pydoc.plaintext)


def test_stubs_name_every_public_name():
    tree = ast.parse((PKG / "__init__.pyi").read_text())
    names = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.ImportFrom):
            names.update(a.asname or a.name for a in node.names)
        elif isinstance(node, (ast.AnnAssign, ast.Assign)):
            targets = [node.target] if isinstance(node, ast.AnnAssign) else node.targets
            names.update(t.id for t in targets if isinstance(t, ast.Name))
    assert set(mbsolve.__all__) <= names, set(mbsolve.__all__) - names
    assert (PKG / "py.typed").exists()
