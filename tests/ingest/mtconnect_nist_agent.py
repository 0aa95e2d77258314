"""The test MTConnect agent (tests/ingest/mtconnect_test_agent.py) serving the NIST smart manufacturing
test bed's real files: its agent's `Devices.xml` as the probe (seven devices, several of them with no
positions, conditions, vendor `x:` types, data items with no subType) and real SHDR logs of some of
those devices replayed as the agent's observations (tests/fixtures/ingest/nist/, public domain).

As cppagent does with an adapter's lines: a line's key is matched to the device's data item by id,
name or `<Source>` (keys it does not know are dropped and counted in `ignored`), the adapter's
timestamps are kept (so the observations carry 2016/2017 times while the agent's header carries
today's), conditions (`key|level|code|severity|qualifier|text`) are sent as `<Condition>` entries,
and with `FilterDuplicates` (set for the Hurco adapters in NIST's agent.cfg) a value equal to the
last one is not sent again. Every data item starts UNAVAILABLE. Values are served as the logs hold
them: the logs were taken from the agent's output (their keys are data item names, not the adapters'
`<Source>` names), so no `nativeUnits` conversion is applied a second time.

The replay is faster than the original: the wall-clock pause between two times of a log is
`min(dt / speed, max_pause_s)` (a day of Mazak data in a few seconds); each device's log keeps its own order.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tests.ingest.mtconnect_test_agent import ReplayAgent, iso

NIST = Path(__file__).resolve().parents[1] / "fixtures" / "ingest" / "nist"
DEVICES_XML = NIST / "Devices.xml"
HURCO = NIST / "Box-OP2-Hurco02-01of20.txt"
MAZAK = NIST / "Mazak01-20161006-head4000.txt"
FILTER_DUPLICATES = {"Hurco01", "Hurco02", "Hurco03", "Hurco04", "Hurco06"}   # NIST's agent.cfg
STREAMS_NS = ('xmlns="urn:mtconnect.org:MTConnectStreams:1.3" '
              'xmlns:x="urn:nist.gov:NistStreams:1.3"')   # NIST's agent.cfg StreamsNamespaces
LEVELS = {"UNAVAILABLE": "Unavailable", "NORMAL": "Normal", "WARNING": "Warning", "FAULT": "Fault"}


@dataclass(frozen=True)
class Item:
    device: str
    component: str      # the element of the component: Linear, Rotary, Path, Controller, Device, ...
    component_name: str
    category: str
    type: str
    sub_type: str
    keys: tuple[str, ...]   # what an adapter line may call it: id, name, Source


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def read_devices(xml: bytes) -> dict[str, Item]:
    """Data item id -> Item, from a Devices.xml (test side: ElementTree, independent of feedlog's parser)."""
    items: dict[str, Item] = {}

    def walk(element: ET.Element, device: str, owner: ET.Element) -> None:
        for child in element:
            tag = _local(child.tag)
            if tag == "DataItems":
                for di in child:
                    if _local(di.tag) != "DataItem":
                        continue
                    source = next((s.text or "" for s in di if _local(s.tag) == "Source"), "")
                    comp = _local(owner.tag)
                    items[di.get("id")] = Item(device, comp, owner.get("name") or owner.get("id", ""),
                                               di.get("category", ""), di.get("type", ""), di.get("subType", ""),
                                               tuple(k for k in (di.get("id"), di.get("name"), source) if k))
            else:
                walk(child, device, child if tag not in ("Components",) else owner)

    root = ET.fromstring(xml)
    for devices in root:
        if _local(devices.tag) != "Devices":
            continue
        for dev in devices:
            walk(dev, dev.get("name"), dev)
    return items


def read_log(path: Path, device: str, items: dict[str, Item]) -> tuple[list[tuple[int, str, str]], int]:
    """(t_ns, item id, text) of an SHDR log's lines for `device`, and the number of keys it does not know."""
    by_key = {k: i for i, it in items.items() if it.device == device for k in it.keys}
    out, ignored, last = [], 0, {}
    for raw in path.read_text().splitlines():
        fields = raw.split("|")
        if len(fields) < 3:
            continue
        item = by_key.get(fields[1])
        if item is None:
            ignored += 1
            continue
        text = "|".join(fields[2:]) if items[item].category == "CONDITION" else fields[2]
        if device in FILTER_DUPLICATES and last.get(item) == text:
            continue
        last[item] = text
        out.append((int(np.datetime64(fields[0].rstrip("Z"), "ns").astype(np.int64)), item, text))
    return out, ignored


class NistAgent(ReplayAgent):
    """Serves NIST's Devices.xml and replays `logs` {device name: SHDR file} (see the module docstring)."""

    def __init__(self, logs: dict[str, Path], *, speed: float = 25.0, max_pause_s: float = 0.02,
                 buffer_size: int = 131072, start_delay_s: float = 0.8, port: int = 0) -> None:
        self.devices_xml = DEVICES_XML.read_bytes()
        self.nist_items = read_devices(self.devices_xml)
        self.device_names = sorted({it.device for it in self.nist_items.values()})
        self.device = ",".join(logs)
        self.items = {i: (it.component, it.component_name, it.category, it.type, it.sub_type, "")
                      for i, it in self.nist_items.items()}
        self.ignored: dict[str, int] = {}
        self.logged: dict[str, list[tuple[int, str, str]]] = {}
        merged = []
        for device, path in logs.items():
            entries, self.ignored[device] = read_log(path, device, self.nist_items)
            self.logged[device] = entries
            t = np.array([e[0] for e in entries], dtype=np.int64)
            pause = np.minimum(np.diff(t, prepend=t[:1]) / speed, max_pause_s * 1e9)
            wall = np.cumsum(pause).astype(np.int64)
            merged += [(int(w), item, text, stamp) for w, (stamp, item, text) in zip(wall, entries)]
        merged.sort(key=lambda e: e[0])
        first = min(e[3] for e in merged)
        self._init_agent(buffer_size=buffer_size, start_delay_s=start_delay_s, port=port,
                         initial_ns=first - 1_000_000_000)   # the agent started before the adapters sent
        self.probe_body = self.devices_xml
        self.observations = merged

    def serves(self, device: str) -> bool:
        return device in self.device_names

    def _of_device(self, entries: list, device: str | None) -> list:
        return entries if device is None else [e for e in entries if self.nist_items[e[1]].device == device]

    def _entry(self, seq: int, item: str, t_ns: int, text: str) -> tuple[str, str]:
        it = self.nist_items[item]
        prefix, _, bare = it.type.rpartition(":")
        element = (f"{prefix}:" if prefix else "") + "".join(p.capitalize() for p in bare.split("_"))
        attrs = f'dataItemId="{item}" timestamp="{iso(t_ns)}" sequence="{seq}"'
        attrs += f' subType="{it.sub_type}"' if it.sub_type else ""
        if it.category == "CONDITION":
            level, *rest = (text.split("|") + [""] * 5)[:5]
            tag = LEVELS.get(level.upper(), "Unavailable")
            code, severity, qualifier, message = rest
            extra = f' type="{it.type}"' + (f' nativeCode="{code}"' if code else "")
            extra += (f' nativeSeverity="{severity}"' if severity else "") + (f' qualifier="{qualifier}"' if qualifier else "")
            return "Condition", f"<{tag} {attrs}{extra}>{_escape(message)}</{tag}>" if message else f"<{tag} {attrs}{extra}/>"
        category = "Samples" if it.category == "SAMPLE" else "Events"
        return category, f"<{element} {attrs}>{_escape(text)}</{element}>"

    def _streams(self, entries, *, next_seq: int | None = None) -> bytes:
        by_device: dict[str, dict[tuple[str, str], list[tuple[str, str]]]] = {}
        for seq, item, t_ns, text in entries:
            it = self.nist_items[item]
            by_device.setdefault(it.device, {}).setdefault((it.component, it.component_name), []).append(
                self._entry(seq, item, t_ns, text))
        devices = []
        for device, comps in by_device.items():
            body = []
            for (comp, cname), elems in comps.items():
                cats = "".join(f"<{cat}>{''.join(e for c, e in elems if c == cat)}</{cat}>"
                               for cat in ("Samples", "Events", "Condition") if any(c == cat for c, _ in elems))
                body.append(f'<ComponentStream component="{comp}" name="{cname}">{cats}</ComponentStream>')
            devices.append(f'<DeviceStream name="{device}" uuid="{device}">{"".join(body)}</DeviceStream>')
        return (f'<?xml version="1.0" encoding="UTF-8"?>\n<MTConnectStreams {STREAMS_NS}>'
                f'{self._header(next_seq=next_seq)}<Streams>{"".join(devices)}</Streams></MTConnectStreams>').encode()


def _escape(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
