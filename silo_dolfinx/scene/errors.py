"""Scene errors: every problem names the section, the key, the value, what is allowed and a fix."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Problem:
    section: str  # "" for top-level keys
    key: str
    message: str  # complete, self-contained sentence(s) including the fix
    also: tuple[str, ...] = ()  # other "section.key"s the problem involves (a product of several keys)

    def __str__(self) -> str:
        where = f"[{self.section}] {self.key}" if self.section else self.key
        return f"{where}: {self.message}"


class SceneError(ValueError):
    """A scene file (or ``--set`` override) that cannot be run, with every problem found."""

    def __init__(self, problems: list[Problem] | Problem, source: str | None = None):
        self.problems = [problems] if isinstance(problems, Problem) else list(problems)
        self.source = source
        head = f"invalid scene{f' {source}' if source else ''}"
        lines = [head + ":"] + [f"  - {p}" for p in self.problems]
        super().__init__("\n".join(lines))

    @property
    def keys(self) -> list[str]:
        """The ``section.key`` names of all problems, and of the keys each involves (handy in tests
        and tools)."""
        return [k for p in self.problems for k in (f"{p.section}.{p.key}" if p.section else p.key, *p.also)]
