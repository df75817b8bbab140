"""A strict reader of the Prometheus text exposition format 0.0.4, as the tests scrape softshockd's
/metrics: every line a HELP, a TYPE or a sample of the family announced just before it, label
values unescaped, histograms checked (cumulative buckets ending in le="+Inf" equal to _count).
Raises ValueError on anything Prometheus would reject."""

from __future__ import annotations

import math
import re
from typing import Dict, Optional, Tuple

_NAME = r"[a-zA-Z_:][a-zA-Z0-9_:]*"
_SAMPLE = re.compile(r"^(" + _NAME + r")(\{(.*)\})? (\S+)$")
_LABEL = re.compile(r'([a-zA-Z_][a-zA-Z0-9_]*)="((?:[^"\\]|\\.)*)"(,|$)')
_SUFFIXES = {"histogram": ("_bucket", "_sum", "_count"), "counter": ("",), "gauge": ("",)}

Labels = Tuple[Tuple[str, str], ...]


def _unescape(v: str) -> str:
    return re.sub(r"\\(.)", lambda m: {"n": "\n"}.get(m.group(1), m.group(1)), v)


def _value(text: str) -> float:
    special = {"+Inf": math.inf, "-Inf": -math.inf, "NaN": math.nan}
    return special[text] if text in special else float(text)


class Metrics:
    """Samples by (name, sorted labels); families' types and help."""

    def __init__(self, text: str):
        self.types: Dict[str, str] = {}
        self.help: Dict[str, str] = {}
        self.samples: Dict[Tuple[str, Labels], float] = {}
        if not text.endswith("\n"):
            raise ValueError("the exposition must end with a newline")
        family: Optional[str] = None
        for n, line in enumerate(text.splitlines(), 1):
            if line.startswith("# HELP "):
                name, _, help_text = line[7:].partition(" ")
                if name in self.help:
                    raise ValueError(f"line {n}: a second HELP for {name}")
                self.help[name] = help_text
                family = name
                continue
            if line.startswith("# TYPE "):
                name, _, kind = line[7:].partition(" ")
                if name != family or kind not in _SUFFIXES or name in self.types:
                    raise ValueError(f"line {n}: bad TYPE line {line!r}")
                self.types[name] = kind
                continue
            m = _SAMPLE.match(line)
            if not m:
                raise ValueError(f"line {n}: not a sample: {line!r}")
            name, labels_text, value = m.group(1), m.group(3) or "", m.group(4)
            if family is None or family not in self.types or not any(
                    name == family + s for s in _SUFFIXES[self.types[family]]):
                raise ValueError(f"line {n}: {name} outside its family ({family})")
            labels = []
            rest = labels_text
            while rest:
                lm = _LABEL.match(rest)
                if not lm:
                    raise ValueError(f"line {n}: bad labels {labels_text!r}")
                labels.append((lm.group(1), _unescape(lm.group(2))))
                rest = rest[lm.end():]
            key = (name, tuple(sorted(labels)))
            if key in self.samples:
                raise ValueError(f"line {n}: a repeated series {line!r}")
            self.samples[key] = _value(value)
        self._check_histograms()

    def _check_histograms(self) -> None:
        for family, kind in self.types.items():
            if kind != "histogram":
                continue
            series: Dict[Labels, list] = {}
            for (name, labels), v in self.samples.items():
                if name == family + "_bucket":
                    le = dict(labels)["le"]
                    rest = tuple(kv for kv in labels if kv[0] != "le")
                    series.setdefault(rest, []).append((_value(le), v))
            for rest, buckets in series.items():
                buckets.sort()
                counts = [c for _, c in buckets]
                if buckets[-1][0] != math.inf or counts != sorted(counts):
                    raise ValueError(f"{family}{rest}: buckets not cumulative up to +Inf")
                if self.samples.get((family + "_count", rest)) != counts[-1]:
                    raise ValueError(f"{family}{rest}: _count differs from the +Inf bucket")

    def get(self, name: str, default: Optional[float] = None, **labels: str) -> Optional[float]:
        """The sample `name` with exactly these labels (default when absent)."""
        return self.samples.get((name, tuple(sorted(labels.items()))), default)

    def total(self, name: str, **labels: str) -> float:
        """Sum over every series of `name` whose labels include these."""
        want = set(labels.items())
        return sum(v for (n, ls), v in self.samples.items() if n == name and want <= set(ls))
