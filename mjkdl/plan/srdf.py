"""MoveIt's SRDF, the parts a planner here uses: the pairs of links whose collisions are
disabled (`<disable_collisions>`, each with its reason) and the planning groups (`<group>`:
joints, links, chains, subgroups) and their named states (`<group_state>`).

`MotionPlanner(robot, srdf=...)` allows the disabled pairs in its allowed-collision matrix
(reason "srdf"); the groups and named states are there to read (a group's joints, a pose).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from ..errors import SpecError
from .limits import read_file


@dataclass(frozen=True)
class SrdfGroup:
    """One `<group>`: its `joints`, `links`, `chains` ((base_link, tip_link) pairs) and
    `subgroups` by name."""

    name: str
    joints: tuple[str, ...]
    links: tuple[str, ...]
    chains: tuple[tuple[str, str], ...]
    subgroups: tuple[str, ...]


@dataclass(frozen=True)
class Srdf:
    """What an SRDF file says: `disabled` pairs of link names with their reason, `groups`
    and named `states` (`<group_state>`: joint name -> value) by name, and the file it was
    read from (`source`)."""

    disabled: tuple[tuple[str, str, str], ...]
    groups: dict[str, SrdfGroup]
    states: dict[str, dict[str, float]]
    source: str

    @classmethod
    def load(cls, path: str | Path) -> Srdf:
        """Read an SRDF file (MoveIt's format)."""
        file, text = read_file(path, "SRDF file")
        try:
            root = ET.fromstring(text)
        except ET.ParseError as error:
            raise SpecError(f"SRDF file {str(file)!r} is not XML: {error}") from None
        if root.tag != "robot":
            raise SpecError(
                f"SRDF file {str(file)!r}: the root element is <{root.tag}>, not <robot>"
            )

        def attribute(element: ET.Element, name: str) -> str:
            value = element.get(name)
            if not value:
                raise SpecError(
                    f"SRDF file {str(file)!r}: a <{element.tag}> has no {name!r} attribute"
                )
            return value

        disabled = tuple(
            (attribute(e, "link1"), attribute(e, "link2"), e.get("reason") or "")
            for e in root.iter("disable_collisions")
        )
        states: dict[str, dict[str, float]] = {}
        for state in root.iter("group_state"):
            name = attribute(state, "name")
            values = {}
            for joint in state.iter("joint"):
                text = attribute(joint, "value")
                try:
                    values[attribute(joint, "name")] = float(text.split()[0])
                except (ValueError, IndexError):
                    raise SpecError(
                        f"SRDF file {str(file)!r}: group_state {name!r} joint "
                        f"{joint.get('name')!r} has value {text!r}, not a number"
                    ) from None
            states[name] = values
        groups = {}
        for element in root.findall("group"):
            name = attribute(element, "name")
            groups[name] = SrdfGroup(
                name,
                tuple(attribute(e, "name") for e in element.findall("joint")),
                tuple(attribute(e, "name") for e in element.findall("link")),
                tuple(
                    (attribute(e, "base_link"), attribute(e, "tip_link"))
                    for e in element.findall("chain")
                ),
                tuple(attribute(e, "name") for e in element.findall("group")),
            )
        return cls(disabled, groups, states, str(file))
