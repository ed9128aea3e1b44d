"""docs/griffe_inherited_args.py: the API reference gives a class the Args entries its base classes
document, as `strategy_parameters` does (tests/test_strategy_registry.py)."""

from pathlib import Path

import pytest

griffe = pytest.importorskip("griffe", reason="griffe comes with mkdocstrings, a test extra: pip install -e '.[test]'")

ROOT = Path(__file__).resolve().parents[1]
TOY_MODULE = '''
class Base:
    """A base.

    Args:
        a: the a.
        b: the b of the base.
    """

    def __init__(self, a: int, b: str = "x"):
        pass


class Child(Base):
    """A child: it documents only what it adds or explains anew.

    Args:
        c: the c.
        b: the b, anew.
    """

    def __init__(self, a: int = 1, b: str = "y", c: float = 0.5):
        pass


class Grandchild(Child):
    """No Args of its own, nor an `__init__`.

    Returns:
        nothing, a section after where Args would stand.
    """
'''


def parameter_tables(tmp_path, extension: bool) -> dict[str, list[tuple]]:
    (tmp_path / "toy_docs.py").write_text(TOY_MODULE)
    extensions = griffe.load_extensions(f"{ROOT / 'docs' / 'griffe_inherited_args.py'}:InheritedArgs") if extension \
        else None
    module = griffe.load("toy_docs", search_paths=[tmp_path], docstring_parser="google", extensions=extensions)
    tables = {}
    for name in ("Base", "Child", "Grandchild"):
        sections = module[name].docstring.parsed
        tables[name] = [(section.kind.value, [(p.name, str(p.annotation), p.value, p.description) for p in section.value]
                         if section.kind is griffe.DocstringSectionKind.parameters else None) for section in sections]
    return tables


def test_a_subclass_table_lists_its_bases_entries_with_its_own_signature(tmp_path):
    tables = parameter_tables(tmp_path, extension=True)
    assert tables["Base"] == [("text", None), ("parameters", [("a", "int", None, "the a."),
                                                              ("b", "str", "'x'", "the b of the base.")])]
    # the constructor's order; a from the base with the child's default; b, documented anew, the child's
    assert tables["Child"] == [("text", None), ("parameters", [("a", "int", "1", "the a."),
                                                               ("b", "str", "'y'", "the b, anew."),
                                                               ("c", "float", "0.5", "the c.")])]
    # the nearest base's entries, in a section of their own before the rest of the docstring
    assert tables["Grandchild"] == [("text", None), ("parameters", tables["Child"][1][1]), ("returns", None)]


def test_without_it_a_subclass_table_lists_only_its_own_entries(tmp_path):
    tables = parameter_tables(tmp_path, extension=False)
    assert [p[0] for p in tables["Child"][1][1]] == ["c", "b"]
    assert [kind for kind, _ in tables["Grandchild"]] == ["text", "returns"]
