"""Records a compiled tick takes as one argument: numba's StructRef, defined in one place.

numba's dispatcher finds the type of every argument in Python at every call: ≈ 50 ns an
array, µs for a named tuple or a structured array (field by field). A controller that hands
its compiled tick tens of arrays would spend more than a tenth of the tick there. A StructRef
carries its type and holds its members unboxed since it was made, so the call costs one
argument. This module is the only place that touches numba's ``structref`` machinery; a
controller declares its record by name and fields::

    TickRecordsType, TickRecords = define_record("TickRecords", ("params", "state"), __name__)

and builds an instance with the proxy's constructor, ``TickRecords(params, state)``, in Python
or in compiled code (a compiled, cached constructor is cheaper at reset:
``numba.njit(cache=True)(lambda p, s: TickRecords(p, s))`` is *not* cacheable, so define a
module-level ``@njit(cache=True)`` function that calls it). Inside compiled code the members
are attributes: ``records.state.phase``.

Both classes are given the caller's module and the names ``<name>Type`` and ``<name>``, and
the caller binds them to those names at module level, so numba's on-disk cache (which pickles
a compiled function's argument types by module and name) finds them again in a new process.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numba
from numba import types
from numba.experimental import structref

__all__ = ["define_record"]


def _unliteral_fields(self: types.StructRef, fields: tuple) -> tuple:
    """The members' types without literal values (a record built from the constant ``3``
    holds an int, not the literal type ``Literal[int](3)``, so one compiled tick serves
    every value)."""
    return tuple((name, types.unliteral(typ)) for name, typ in fields)


def _getter(field: str) -> Callable[[structref.StructRefProxy], object]:
    """Python's read of one member: a compiled accessor, compiled on first use (Python reads
    records rarely, at reset and in tests; compiled code reads members directly)."""
    namespace: dict = {}
    exec(f"def get(record):\n    return record.{field}\n", namespace)  # noqa: S102
    return numba.njit(namespace["get"])


def define_record(
    name: str, fields: Sequence[str], module: str
) -> tuple[type[types.StructRef], type[structref.StructRefProxy]]:
    """A StructRef record ``name`` with these ``fields``: (numba's type class, the proxy class).

    Args:
        name: the record's Python name; the type class is called ``name + "Type"``.
        fields: the members, in the constructor's argument order.
        module: the module that binds both classes at top level under those names (pass
            ``__name__``); numba's cache finds them there.

    Returns:
        ``(RecordType, Record)``: register-time type class and the proxy a caller constructs
        with the members as positional arguments; each member is readable as an attribute in
        Python and in compiled code.
    """
    if not name.isidentifier() or not fields or not all(f.isidentifier() for f in fields):
        raise ValueError(f"record {name!r}: a name and identifier fields are needed, got {fields}")
    if len(set(fields)) != len(fields):
        raise ValueError(f"record {name!r}: repeated field in {tuple(fields)}")
    record_type = type(
        f"{name}Type",
        (types.StructRef,),
        {"preprocess_fields": _unliteral_fields, "__module__": module},
    )
    record_type.__qualname__ = record_type.__name__
    structref.register(record_type)
    members = {field: property(_getter(field), doc=f"member {field}") for field in fields}
    proxy = type(
        name,
        (structref.StructRefProxy,),
        {
            "__module__": module,
            "__doc__": f"StructRef record with members {', '.join(fields)}.",
            **members,
        },
    )
    proxy.__qualname__ = name
    structref.define_proxy(proxy, record_type, list(fields))
    return record_type, proxy
