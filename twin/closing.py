"""The base of everything that holds a resource (a rendering context, later a device):
``close()`` and the context-manager protocol that calls it."""

from __future__ import annotations

from abc import ABC, abstractmethod
from types import TracebackType
from typing import Self


class Closing(ABC):
    """Something to :meth:`close` when done; ``with`` closes it on the way out."""

    @abstractmethod
    def close(self) -> None:
        """Release what this object holds. Calling it twice is harmless."""

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
