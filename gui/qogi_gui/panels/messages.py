"""The message log: what the user is told (info, warnings, errors)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import List, Optional

__all__ = ["Message", "MessageLog", "MAX_MESSAGES"]

MAX_MESSAGES = 200


@dataclass
class Message:
    level: str  # "info", "warning" or "error"
    text: str
    time_s: float


class MessageLog:
    """The last :data:`MAX_MESSAGES` messages, oldest first. Actions report
    through it instead of raising: :meth:`error` returns False so that an
    action can ``return self.vm.log.error(...)``."""

    def __init__(self):
        self.messages: List[Message] = []

    def say(self, level: str, text: str) -> None:
        self.messages.append(Message(level, str(text), time.time()))
        del self.messages[:-MAX_MESSAGES]

    def info(self, text: str) -> None:
        self.say("info", text)

    def warn(self, text: str) -> None:
        self.say("warning", text)

    def error(self, text: str) -> bool:
        self.say("error", text)
        return False

    @property
    def last(self) -> Optional[Message]:
        return self.messages[-1] if self.messages else None
