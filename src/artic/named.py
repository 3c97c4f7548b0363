"""`Registry`: things registered by name (tasks, object categories), looked up with a
one-line error that lists the known names."""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

from artic.errors import InputError

T = TypeVar("T")


class Registry(dict[str, T]):
    """A dict of registered things by name. `register(name)` is a decorator (registering
    a name twice is a programming error, ValueError); `lookup(name)` is the thing or
    InputError `"{field}: unknown {what} 'x'; known {plural}: a, b"`."""

    def __init__(self, field: str, what: str, plural: str) -> None:
        super().__init__()
        self.field, self.what, self.plural = field, what, plural

    def register(self, name: str) -> Callable[[T], T]:
        def decorate(thing: T) -> T:
            if name in self:
                raise ValueError(f"{self.what} {name!r} is already registered")
            self[name] = thing
            return thing

        return decorate

    def lookup(self, name: str) -> T:
        if name not in self:
            known = ", ".join(sorted(self))
            raise InputError(
                f"{self.field}: unknown {self.what} {name!r}; known {self.plural}: {known}"
            )
        return self[name]
