"""Readers for deploy/: the Dockerfile's instructions by stage, and the daemon's settings as
`softshockd --help` lists them. Shared by the deploy tests so each fact is parsed once.

Environment (set by tests/CMakeLists.txt): SOFTSHOCKD, SOFTSHOCK, SOFTSHOCK_SOLVE (binary paths)
and SOFTSHOCK_SOURCE_DIR (the repository).
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Dict, List, Optional

SOURCE_DIR = os.environ.get("SOFTSHOCK_SOURCE_DIR",
                            os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..")))
DEPLOY_DIR = os.path.join(SOURCE_DIR, "deploy")
DOCKERFILE = os.path.join(DEPLOY_DIR, "Dockerfile")
SOFTSHOCKD = os.environ.get("SOFTSHOCKD", "softshockd")
SOFTSHOCK = os.environ.get("SOFTSHOCK", "softshock")
SOFTSHOCK_SOLVE = os.environ.get("SOFTSHOCK_SOLVE", "softshock-solve")


@dataclass
class Instruction:
    keyword: str  # upper case: FROM, RUN, COPY, ENV, ...
    args: str     # the rest of the logical line, continuations joined
    line: int     # where it starts (1-based), for messages


@dataclass
class Stage:
    name: str
    base: str
    instructions: List[Instruction] = field(default_factory=list)

    def all(self, keyword: str) -> List[Instruction]:
        return [i for i in self.instructions if i.keyword == keyword]

    def last(self, keyword: str) -> Optional[Instruction]:
        found = self.all(keyword)
        return found[-1] if found else None

    def env(self) -> Dict[str, str]:
        """ENV key=value pairs (the modern form only; the file uses nothing else)."""
        out: Dict[str, str] = {}
        for i in self.all("ENV"):
            for pair in shlex.split(i.args):
                key, sep, value = pair.partition("=")
                if not sep:
                    raise ValueError(f"Dockerfile:{i.line}: ENV without '=': {i.args}")
                out[key] = value
        return out

    def exec_form(self, keyword: str) -> List[str]:
        """ENTRYPOINT / CMD in JSON exec form (a shell form would add /bin/sh -c)."""
        i = self.last(keyword)
        if i is None:
            return []
        value = json.loads(i.args)
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise ValueError(f"Dockerfile:{i.line}: {keyword} is not in exec form")
        return value

    def healthcheck(self) -> (Dict[str, str], List[str]):
        """(options such as {'interval': '30s'}, the command in exec form)."""
        i = self.last("HEALTHCHECK")
        if i is None:
            raise ValueError("no HEALTHCHECK")
        options: Dict[str, str] = {}
        rest = i.args
        while rest.startswith("--"):
            word, _, rest = rest.partition(" ")
            key, _, value = word[2:].partition("=")
            options[key] = value
            rest = rest.lstrip()
        keyword, _, command = rest.partition(" ")
        if keyword.upper() != "CMD":
            raise ValueError(f"Dockerfile:{i.line}: HEALTHCHECK {keyword}")
        return options, json.loads(command)

    def user(self) -> str:
        i = self.last("USER")
        return i.args.strip() if i else "root"


def read_dockerfile(path: str = DOCKERFILE) -> (Dict[str, str], List[Stage]):
    """(global ARGs before the first FROM, the stages in order)."""
    instructions: List[Instruction] = []
    pending, start = "", 0
    with open(path, encoding="utf-8") as f:
        for n, raw in enumerate(f, 1):
            line = raw.rstrip("\n")
            if not pending and (not line.strip() or line.lstrip().startswith("#")):
                continue
            if pending and line.lstrip().startswith("#"):
                continue  # comment lines inside a continued instruction are dropped
            if not pending:
                start = n
            if line.endswith("\\"):
                pending += line[:-1] + " "
                continue
            text = (pending + line).strip()
            pending = ""
            keyword, _, args = text.partition(" ")
            instructions.append(Instruction(keyword.upper(), re.sub(r"\s+", " ", args).strip(),
                                            start))
    args: Dict[str, str] = {}
    stages: List[Stage] = []
    for i in instructions:
        if i.keyword == "FROM":
            words = i.args.split()
            name = words[2] if len(words) == 3 and words[1].upper() == "AS" else str(len(stages))
            stages.append(Stage(name, words[0]))
        elif not stages:
            if i.keyword != "ARG":
                raise ValueError(f"Dockerfile:{i.line}: {i.keyword} before FROM")
            key, _, value = i.args.partition("=")
            args[key] = value
        else:
            stages[-1].instructions.append(i)
    return args, stages


def runtime_stage() -> Stage:
    """The stage the image runs: the last one."""
    return read_dockerfile()[1][-1]


@lru_cache(maxsize=None)
def daemon_settings() -> Dict[str, str]:
    """{flag: environment variable} for every setting `softshockd --help` documents."""
    text = subprocess.run([SOFTSHOCKD, "--help"], check=True, capture_output=True,
                          text=True).stdout
    found = dict(re.findall(r"^  --([a-z-]+)(?: [A-Z]+)?  \((SOFTSHOCK_[A-Z_]+)\)$", text,
                            re.MULTILINE))
    if len(found) < 10:
        raise ValueError("softshockd --help lists too few settings:\n" + text)
    return found


def port_of(address: str) -> int:
    return int(address.rsplit(":", 1)[1])
