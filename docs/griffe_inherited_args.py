"""A Griffe extension that gives a class's parameter table the entries its base classes document.

A start strategy documents each constructor parameter once, under Args in the docstring of the class
that introduces it; a subclass documents only the parameters it adds or explains anew, and
`strategy_parameters` (agents/strategy_registry.py) reads the rest from its base classes. This
extension does the same for the API reference: once Griffe has loaded a package, each class's
Parameters section gains, for every parameter of its `__init__` it does not document itself, the
Args entry of the nearest class in its method resolution order that does, with the class's own
annotation and default; the section then lists its entries in the constructor's order.
"""

from __future__ import annotations

from typing import Any, Iterator

import griffe


def classes(obj: griffe.Object) -> Iterator[griffe.Class]:
    """Every class defined in `obj`, nested ones included (imported names are aliases: left out)."""
    for member in obj.members.values():
        if member.is_alias or not (member.is_module or member.is_class):
            continue
        if member.is_class:
            yield member
        yield from classes(member)


def init_parameters(cls: griffe.Class) -> griffe.Parameters:
    """The parameters of the `__init__` that `cls` defines or inherits, the first along its method
    resolution order."""
    for owner in (cls, *cls.mro()):
        init = owner.members.get("__init__")
        if init is not None and init.is_function:
            return init.parameters
    return griffe.Parameters()


def args_entries(cls: griffe.Class) -> dict[str, str]:
    """name -> description of each entry under Args in the docstring of `cls` itself.

    Read from a copy of the docstring detached from the class: parsing the class's own docstring
    looks up its inherited members, and when that first happens decides which of them the API
    reference lists among the objects it links to; so each class's own docstring is still parsed
    only when it is rendered, as without this extension.
    """
    if cls.docstring is None:
        return {}
    sections = griffe.parse_google(griffe.Docstring(cls.docstring.value), warnings=False)
    return {entry.name: entry.description for section in sections
            if section.kind is griffe.DocstringSectionKind.parameters for entry in section.value}


class InheritingDocstring(griffe.Docstring):
    """A class's docstring whose Parameters section, once parsed, holds the `inherited` entries too
    (name -> description), with the class's annotations and defaults, in the constructor's order."""

    def __init__(self, docstring: griffe.Docstring, inherited: dict[str, str]):
        super().__init__(docstring.value, lineno=docstring.lineno, endlineno=docstring.endlineno,
                         parent=docstring.parent, parser=docstring.parser, parser_options=docstring.parser_options)
        self.inherited = inherited

    def parse(self, parser: Any = None, **options: Any) -> list[griffe.DocstringSection]:
        sections = super().parse(parser, **options)
        parameters = {parameter.name: parameter for parameter in init_parameters(self.parent)}
        kinds = [section.kind for section in sections]
        entries = [entry for section in sections if section.kind is griffe.DocstringSectionKind.parameters
                   for entry in section.value]
        # the description is the base's; the annotation and default are this class's, as Griffe reads them
        entries += [griffe.DocstringParameter(name, description=text, annotation=parameters[name].annotation,
                                              value=parameters[name].default)
                    for name, text in self.inherited.items()]
        order = list(parameters)
        entries.sort(key=lambda entry: order.index(entry.name) if entry.name in order else len(order))
        merged = griffe.DocstringSectionParameters(entries)
        if griffe.DocstringSectionKind.parameters in kinds:  # the first Parameters section holds them all
            first = kinds.index(griffe.DocstringSectionKind.parameters)
            merged.title = sections[first].title
            return [*sections[:first], merged, *(section for section in sections[first + 1:]
                                                 if section.kind is not griffe.DocstringSectionKind.parameters)]
        # a new section after the leading text, where Args would stand
        first = next((i for i, kind in enumerate(kinds) if kind is not griffe.DocstringSectionKind.text), len(kinds))
        return [*sections[:first], merged, *sections[first:]]


def inherit_args(cls: griffe.Class) -> None:
    """Give `cls` the Args entries of its base classes for the parameters of its `__init__` that it
    does not document itself, the nearest base's entry winning."""
    if cls.docstring is None:
        return
    parameters = {parameter.name for parameter in init_parameters(cls)} - {"self"}
    own = args_entries(cls)
    inherited: dict[str, str] = {}
    for base in reversed(cls.mro()):  # the nearest base last: its entries win
        inherited.update({name: text for name, text in args_entries(base).items()
                          if name in parameters and name not in own})
    if inherited:
        cls.docstring = InheritingDocstring(cls.docstring, inherited)


class InheritedArgs(griffe.Extension):
    """Give every class of a loaded package the Args entries its base classes document."""

    def on_package(self, *, pkg: griffe.Module, loader: griffe.GriffeLoader, **kwargs: Any) -> None:
        for cls in classes(pkg):
            inherit_args(cls)
