"""No call paid twice: a paid model's replies kept on disk and replayed for the same request.

A backend that says what it would send (:meth:`LLMBackend.cache_request
<safeembodai_core.contracts.components.LLMBackend.cache_request>`: the litellm backends) is wrapped, per
trial, in a :class:`CachedBackend`. Its key is the SHA-256 of the trial's id, the exact request
(model, messages with their images, sampling, seed, response format) and how many times the trial
has asked that same request before -- so the same request at the same point of a trial with the
same id gets the same reply back: another trial or arm never shares an answer (its id differs), and
a trial that asks twice the same thing (a robot stuck in place) gets two calls. A resumed trial, cut
off mid-way, replays its first steps instead of paying for them again; a run repeated with the same
scenario and seed replays all of it (so it measures nothing new: ``--refresh`` calls again,
``--no-cache`` keeps nothing).

The cache is a folder of small JSON files, one per reply, by default the run folder's
``responses/``; ``ablate --cache DIR`` shares ``DIR/responses/`` between runs. A stored reply is
read back as hostile input: only a regular file of bounded size is opened (no symlink followed),
its fields are type- and size-checked, and the loop reads its text as strictly as a live one. Keys
are hashes and replies are stored as the backend returned them (the backend masks its key out of
the text first); a reply that still holds a registered key in any encoding a reflecting server
uses (:func:`~safeembodai_core.trust.redaction.secret_encoding`: base64, hex, reversed, ...) is not kept,
and the log says which encoding, so no credential is written. A reply that cannot be kept (a full disk) is logged
and the trial goes on with it.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import stat
import threading
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..contracts.components import LLMBackend
from ..errors import SafeEmbodAIError
from ..logs import get_logger
from ..models import ControlLimits, Prompt, TokenUsage
from ..models.reply import ENVELOPE_ERROR_CHARS, BackendReply, finish_reason_text, plain_token
from ..trust.quoting import quote_untrusted
from ..trust.redaction import secret_encoding
from ..runs.files import read_regular_file, read_run_text

log = get_logger(__name__)

CACHE_DIR = "responses"
#: The run folder's word on its cache (written by ``ablate``, read by every worker).
SETTINGS_FILE = "response_cache.json"
#: The largest stored reply read back (a reply's text is bounded far below by the loop).
MAX_STORED_BYTES = 4_000_000
#: Each trial's index of its keys (``<folder>/trials/<sha256 of the trial id>.keys``, a key a line).
INDEX_DIR = "trials"
MAX_INDEX_BYTES = 4_000_000
_KEY = re.compile(r"[0-9a-f]{64}:[0-9]{1,9}")
_TEXT_FIELDS = ("text", "model", "finish_reason", "reasoning", "envelope_error", "origin")


@dataclass(frozen=True)
class CacheSettings:
    """Where a run keeps replies (``folder``: None for the run folder) and whether it reads them back
    (``read``: False with ``--refresh``); ``enabled`` False keeps nothing (``--no-cache``)."""

    enabled: bool = True
    folder: str | None = None
    read: bool = True

    def write(self, run_dir: str | Path) -> None:
        target = Path(run_dir) / SETTINGS_FILE
        try:
            target.write_text(json.dumps(asdict(self)) + "\n", encoding="utf-8")
        except OSError as error:
            raise SafeEmbodAIError(f"cannot write {target}: {error.strerror or error}") from None

    @classmethod
    def recorded(cls, run_dir: str | Path) -> "CacheSettings":
        """What the run folder says; the default (the run folder's own cache, read and written) when
        it says nothing."""
        marker = Path(run_dir) / SETTINGS_FILE
        try:
            data = json.loads(read_run_text(marker, 65_536))
        except FileNotFoundError:
            return cls()
        except (OSError, json.JSONDecodeError, RecursionError) as error:
            raise SafeEmbodAIError(f"{marker} is unreadable: {error}") from None
        if (not isinstance(data, dict) or set(data) != {"enabled", "folder", "read"}
                or not isinstance(data["enabled"], bool) or not isinstance(data["read"], bool)
                or not (data["folder"] is None or isinstance(data["folder"], str) and 0 < len(data["folder"]) < 4096
                        and Path(data["folder"]).is_absolute())):
            raise SafeEmbodAIError(f"{marker} must hold enabled, folder (absolute) and read, as written by ablate")
        return cls(data["enabled"], data["folder"], data["read"])

    def path(self, run_dir: str | Path) -> Path:
        return Path(self.folder).expanduser() / CACHE_DIR if self.folder else Path(run_dir) / CACHE_DIR


class ResponseCache:
    """Replies by key, one small JSON file each under ``folder`` (``<key[:2]>/<key>.json``): written
    aside and renamed into place, so a reader never sees half a reply and workers and threads need no
    lock; a file that is not a regular file, too large or not a reply is a miss."""

    def __init__(self, folder: str | Path, read: bool = True) -> None:
        self.folder, self.read = Path(folder), read
        self.hits = self.misses = 0
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise SafeEmbodAIError(f"response cache {self.folder}: {error.strerror or error}") from None
        if self.folder.is_symlink() or not self.folder.is_dir():
            raise SafeEmbodAIError(f"response cache {self.folder} is not a folder")

    def _path(self, key: str) -> Path:
        return self.folder / key[:2] / f"{key}.json"

    def get(self, key: str) -> BackendReply | None:
        if not self.read:
            return None
        reply = stored_reply(_read_regular(self._path(key), folder=self.folder))
        if reply is None:
            self.misses += 1
            return None
        self.hits += 1
        return reply

    def put(self, key: str, reply: BackendReply, trial_id: str | None = None) -> None:
        """Keep ``reply`` (and, with ``trial_id``, note its key in the trial's index, so a worker on
        another machine can be handed the trial's replies: :meth:`replies_of`); a reply that cannot be
        kept is logged, never a reason to lose a paid answer."""
        try:
            self.put_text(key, stored_text(reply), trial_id)
        except ValueError as error:  # a number JSON cannot hold
            log.warning("cache.unkept_reply", cache=str(self.folder), error=str(error))

    def put_text(self, key: str, text: str, trial_id: str | None = None) -> None:
        """Keep a reply already in its stored form (the caller has read it with :func:`stored_reply`)."""
        if not _KEY.fullmatch(key):
            raise ValueError(f"not a response cache key: {key[:80]!r}")
        held = secret_encoding(text)
        if held is not None:  # a reflecting server's copy of the key: the trial goes on, nothing is kept
            log.warning("cache.unkept_reply", cache=str(self.folder), error=f"the reply holds the API key ({held})")
            return
        target = self._path(key)
        aside = target.with_name(f".{target.name}.{os.getpid()}.{threading.get_ident()}")
        try:
            target.parent.mkdir(exist_ok=True)
            known = target.exists()  # a reply called again (--refresh): its key is in the index already
            aside.write_text(text, encoding="utf-8")
            os.replace(aside, target)
            if trial_id is not None and not known:
                self._note_key(trial_id, key)
        except OSError as error:  # the reply, or only its index line (then a worker elsewhere calls again)
            log.warning("cache.unkept_reply", cache=str(self.folder), error=str(error))
            aside.unlink(missing_ok=True)

    def _index(self, trial_id: str) -> Path:
        return self.folder / INDEX_DIR / (hashlib.sha256(trial_id.encode("utf-8")).hexdigest() + ".keys")

    def _note_key(self, trial_id: str, key: str) -> None:
        index = self._index(trial_id)
        index.parent.mkdir(exist_ok=True)
        # O_NONBLOCK: a FIFO put at the index must not hang the run (it is refused below)
        flags = os.O_WRONLY | os.O_APPEND | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
        descriptor = os.open(index, flags, 0o644)
        try:
            if not stat.S_ISREG(os.fstat(descriptor).st_mode):
                raise OSError(f"{index} is not a regular file")
            os.write(descriptor, (key + "\n").encode("ascii"))
        finally:
            os.close(descriptor)

    def replies_of(self, trial_id: str) -> dict[str, str]:
        """The stored replies of ``trial_id`` (key -> stored text, each one :func:`stored_reply`
        accepts), from the trial's index; empty when the cache is not read (``--refresh``). Replies
        kept before the index existed are not found here (a worker on another machine calls again)."""
        if not self.read:
            return {}
        listed = _read_regular(self._index(trial_id), MAX_INDEX_BYTES, self.folder) or ""
        replies: dict[str, str] = {}
        for key in dict.fromkeys(listed.splitlines()):
            text = _read_regular(self._path(key), folder=self.folder) if _KEY.fullmatch(key) else None
            if text is not None and stored_reply(text) is not None:
                replies[key] = text
        return replies

    def close(self) -> None:
        """Nothing to release: every reply is its own file."""


def stored_text(reply: BackendReply) -> str:
    """``reply`` as the cache stores it (JSON; raises ValueError for a number JSON cannot hold)."""
    data = asdict(reply)
    data["usage"] = reply.usage.model_dump()
    return json.dumps(data, allow_nan=False)


def _read_regular(path: Path, limit: int = 0, folder: Path | None = None) -> str | None:
    """The text of ``path`` if it is a regular file (no symlink followed below ``folder``, the cache's,
    never a FIFO) of at most ``limit`` bytes (default :data:`MAX_STORED_BYTES`) in UTF-8; else None."""
    data = read_regular_file(path, limit or MAX_STORED_BYTES, folder)
    try:
        return data.decode("utf-8") if data is not None else None
    except UnicodeDecodeError:
        return None


def stored_reply(text: Any) -> BackendReply | None:
    """A stored reply read back, or None when it is not one (wrong types, too large, not JSON)."""
    if not isinstance(text, str) or len(text) > MAX_STORED_BYTES:
        return None
    try:
        data = json.loads(text)
        if not isinstance(data, dict):
            return None
        fields = {name: data.get(name) for name in _TEXT_FIELDS}
        if not isinstance(fields["text"], str):
            return None
        if any(v is not None and not isinstance(v, str) for v in fields.values()):
            return None
        choices, latency = data.get("choices"), data.get("latency_s", 0.0)
        if choices is not None and (type(choices) is not int or choices < 0):
            return None
        if type(latency) not in (int, float) or not 0 <= latency < 86_400:
            return None
        usage = TokenUsage.model_validate(data.get("usage") or {})
        # cleaned as a live reply is: a cache file could hold anything in these fields
        return BackendReply(text=fields["text"], usage=usage, latency_s=float(latency),
                            model=plain_token(fields["model"]) if fields["model"] else "",
                            finish_reason=finish_reason_text(fields["finish_reason"]), reasoning=fields["reasoning"],
                            choices=choices, envelope_error=_quoted(fields["envelope_error"]),
                            origin=plain_token(fields["origin"], 200) if fields["origin"] else None)
    except (ValueError, TypeError, RecursionError):
        return None


def _quoted(error: str | None) -> str | None:
    """A stored envelope error as the file's words, not ours: quoted as an LLM's words are
    (:func:`~safeembodai_core.trust.quoting.quote_untrusted`), so the retry prompt never repeats it bare."""
    return None if error is None else quote_untrusted(error, ENVELOPE_ERROR_CHARS)


def request_key(trial_id: str, request: dict[str, Any]) -> str:
    """The SHA-256 of a trial's request, canonical (sorted keys, no spaces)."""
    text = json.dumps({"trial": trial_id, "request": request}, sort_keys=True, separators=(",", ":"),
                      ensure_ascii=False, default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


class CachedBackend(LLMBackend):
    """One trial's backend with its replies kept in, and served from, ``cache``."""

    def __init__(self, inner: LLMBackend, cache: ResponseCache, trial_id: str) -> None:
        self.inner, self.cache, self.trial_id = inner, cache, trial_id
        self._asked: dict[str, int] = {}

    def prepare_attempt(self, index: int, limits: ControlLimits, rng: np.random.Generator) -> dict[str, Any] | None:
        return self.inner.prepare_attempt(index=index, limits=limits, rng=rng)

    def complete(self, prompt: Prompt, rng: np.random.Generator) -> BackendReply:
        request = self.inner.cache_request(prompt)
        if request is None:
            return self.inner.complete(prompt, rng)
        digest = request_key(self.trial_id, request)
        asked = self._asked.get(digest, 0)
        self._asked[digest] = asked + 1
        key = f"{digest}:{asked}"
        kept = self.cache.get(key)
        if kept is not None:
            log.debug("cache.hit", trial=self.trial_id, key=digest[:16])
            return kept
        reply = self.inner.complete(prompt, rng)
        self.cache.put(key, reply, self.trial_id)
        return reply

    def cost(self, prompt_tokens: int, completion_tokens: int) -> float | None:
        return self.inner.cost(prompt_tokens, completion_tokens)

    def preflight(self) -> None:
        self.inner.preflight()

    def close(self) -> None:
        self.inner.close()
