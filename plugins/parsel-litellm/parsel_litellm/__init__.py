"""A language-model provider for any model litellm supports (hosted APIs, local servers).

Choose the model with ``--model`` (``openai/gpt-4o``, ``anthropic/claude-3-5-sonnet-latest``,
``ollama/llama3`` ...; or ``PARSEL_LLM_MODEL``). Keys come from the environment variables
litellm reads (``OPENAI_API_KEY``, ``ANTHROPIC_API_KEY`` ...) or the ``api_key`` option;
``api_base`` points at an OpenAI-compatible server (``--api-base http://127.0.0.1:8000/v1``).

Calls time out after ``timeout`` seconds and are retried ``retries`` times with
exponential backoff on rate limits (429), server errors (5xx), dropped connections and
timeouts; other errors (a bad key, an unknown model) fail at once. A call that fails for
good stops the run (``LiteLLMError.stops_run``): the other prompts are not sent.

With the ``image`` option (PNG bytes, ``parsel edit --with-image``) the prompt goes as a
text part followed by an image part (a base64 data URL); a model that litellm's model
list says takes no images is refused before any call. Every error is a
:class:`LiteLLMError` with one line saying what happened. Token counts and cost (from
litellm's bundled price list) come back with each :class:`Completion`.

litellm is imported on first use, not when the plugin loads, and
``LITELLM_LOCAL_MODEL_COST_MAP=True`` is set first so that importing it never fetches
the price list from the network.
"""

from __future__ import annotations

import base64
import os
import random
import threading
import time
from typing import Any

from parsel_core import hookimpl
from parsel_core.errors import ParselError
from parsel_core.interfaces import Completion, LLMProvider

DEFAULT_TIMEOUT = 60.0
DEFAULT_RETRIES = 3
DEFAULT_BACKOFF = 1.0
MAX_BACKOFF = 30.0
RETRY_STATUS = frozenset({408, 409, 425, 429, 500, 502, 503, 504, 520, 522, 524, 529})

_lock = threading.Lock()
_module: Any = None


class LiteLLMError(ParselError):
    """A call that failed for good (after retries, or at once for errors retrying cannot fix).

    ``stops_run`` tells the language layer not to send the run's other calls: an error that
    survived the retries (a bad key, a bad request, an unknown model, a server that keeps
    failing or hangs) would only repeat for each of them.
    """

    stops_run = True


def load_litellm() -> Any:
    """Import litellm once, with its local price list and without telemetry or debug chatter."""
    global _module
    with _lock:
        if _module is None:
            os.environ.setdefault("LITELLM_LOCAL_MODEL_COST_MAP", "True")
            try:
                import litellm
            except ImportError as exc:
                raise LiteLLMError("the litellm provider needs the litellm package (pip install litellm)") from exc
            for name, value in (("telemetry", False), ("suppress_debug_info", True)):
                if hasattr(litellm, name):
                    setattr(litellm, name, value)
            _module = litellm
        return _module


def _status(exc: BaseException) -> int | None:
    for attr in ("status_code", "code"):
        value = getattr(exc, attr, None)
        if isinstance(value, int):
            return value
    response = getattr(exc, "response", None)
    value = getattr(response, "status_code", None)
    return value if isinstance(value, int) else None


def _retry_after(exc: BaseException) -> float | None:
    """Seconds the server asked us to wait (``Retry-After``), if it said."""
    headers = getattr(exc, "litellm_response_headers", None) or getattr(getattr(exc, "response", None), "headers",
                                                                         None)
    try:
        value = headers.get("retry-after") if headers is not None else None
        return max(0.0, float(value)) if value is not None else None
    except (TypeError, ValueError, AttributeError):
        return None


def classify(exc: BaseException, litellm: Any) -> str:
    """``timeout``, ``retry`` (rate limit, server or connection error) or ``fatal``."""
    timeout_types = tuple(t for t in (getattr(litellm, "Timeout", None),) if isinstance(t, type))
    if isinstance(exc, timeout_types) or isinstance(exc, TimeoutError) or "timed out" in str(exc).lower():
        return "timeout"
    retry_types = tuple(t for t in (getattr(litellm, name, None) for name in (
        "RateLimitError", "InternalServerError", "ServiceUnavailableError", "APIConnectionError",
        "BadGatewayError")) if isinstance(t, type))
    status = _status(exc)
    if status in RETRY_STATUS or (status is not None and status >= 500) or isinstance(exc, retry_types):
        return "retry"
    return "fatal"


def _first_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text[:300] + ("..." if len(text) > 300 else "")


def check_vision(litellm: Any, model: str) -> None:
    """Refuse an image for a model litellm's model list knows but does not mark as taking
    images; a model the list does not know (a local server's) gets the image."""
    try:
        info = litellm.get_model_info(model=model)
    except Exception:  # not in the list: nothing known either way
        return
    if isinstance(info, dict) and not info.get("supports_vision"):
        raise LiteLLMError(f"litellm: {model} does not take images (litellm's model list); "
                           "leave out --with-image or choose a vision model")


class LiteLLMProvider(LLMProvider):
    """Prompts any litellm model; options: model, api_base, api_key, timeout, retries, backoff,
    temperature, max_tokens."""

    name = "litellm"
    cacheable = True

    def complete(self, prompt: str, *, task: str, samples: int = 1, **options: Any) -> list[Completion]:
        model = options.get("model") or os.environ.get("PARSEL_LLM_MODEL")
        if not model:
            raise LiteLLMError("the litellm provider needs a model: --model NAME (e.g. openai/gpt-4o) "
                               "or PARSEL_LLM_MODEL")
        return [self._one(prompt, model, options) for _ in range(samples)]

    def _one(self, prompt: str, model: str, options: dict[str, Any]) -> Completion:
        litellm = load_litellm()
        timeout = float(options.get("timeout") or DEFAULT_TIMEOUT)
        retries = int(options["retries"]) if options.get("retries") is not None else DEFAULT_RETRIES
        backoff = float(options["backoff"]) if options.get("backoff") is not None else DEFAULT_BACKOFF
        content: Any = prompt
        if options.get("image") is not None:
            check_vision(litellm, model)
            url = "data:image/png;base64," + base64.b64encode(bytes(options["image"])).decode("ascii")
            content = [{"type": "text", "text": prompt}, {"type": "image_url", "image_url": {"url": url}}]
        kwargs: dict[str, Any] = {
            "model": model, "messages": [{"role": "user", "content": content}], "timeout": timeout,
            "num_retries": 0, "max_retries": 0,
        }
        api_base = options.get("api_base")
        if api_base:
            kwargs["api_base"] = api_base
        api_key = options.get("api_key") or os.environ.get("PARSEL_LLM_API_KEY")
        if not api_key and api_base and model.startswith("openai/") and not os.environ.get("OPENAI_API_KEY"):
            api_key = "no-key"  # local OpenAI-compatible servers rarely check it, but the client needs one
        if api_key:
            kwargs["api_key"] = api_key
        for name in ("temperature", "max_tokens", "top_p"):
            if options.get(name) is not None:
                kwargs[name] = options[name]
        where = f"{model}" + (f" at {api_base}" if api_base else "")
        attempts = 0
        while True:
            attempts += 1
            started = time.perf_counter()
            try:
                response = litellm.completion(**kwargs)
            except Exception as exc:
                kind = classify(exc, litellm)
                if kind == "fatal":
                    raise LiteLLMError(f"litellm: {where}: {_first_line(exc)}") from None
                if attempts > retries:
                    if kind == "timeout":
                        raise LiteLLMError(f"litellm: {where} timed out after {timeout:g} s "
                                           f"({attempts} attempt{'s' if attempts > 1 else ''})") from None
                    status = _status(exc)
                    raise LiteLLMError(f"litellm: {where} failed after {attempts} attempts"
                                       + (f" (HTTP {status})" if status else "") + f": {_first_line(exc)}") from None
                delay = _retry_after(exc)
                if delay is None:
                    delay = backoff * 2 ** (attempts - 1)
                    delay += random.uniform(0, 0.1 * delay)
                time.sleep(min(delay, MAX_BACKOFF))
                continue
            return self._completion(litellm, response, attempts, time.perf_counter() - started)

    @staticmethod
    def _completion(litellm: Any, response: Any, attempts: int, seconds: float) -> Completion:
        try:
            text = response.choices[0].message.content
        except (AttributeError, IndexError, KeyError, TypeError):
            raise LiteLLMError("litellm: the reply has no message content") from None
        usage = getattr(response, "usage", None)
        prompt_tokens = int(getattr(usage, "prompt_tokens", 0) or 0)
        completion_tokens = int(getattr(usage, "completion_tokens", 0) or 0)
        meta: dict[str, Any] = {"attempts": attempts, "seconds": round(seconds, 4),
                                "model": getattr(response, "model", None)}
        try:
            cost = float(litellm.completion_cost(completion_response=response) or 0.0)
            meta["cost_known"] = True
        except Exception:  # a model missing from the price list has no known cost
            cost = 0.0
            meta["cost_known"] = False
        return Completion(text or "", prompt_tokens, completion_tokens, cost, meta)


@hookimpl
def parsel_llm_providers():
    return [LiteLLMProvider()]
