"""The litellm provider against a fake OpenAI-compatible server on 127.0.0.1.

No test reaches beyond the loopback interface: a guard makes any other connection an
error, and litellm is told to use its bundled price list before it is imported.
"""

from __future__ import annotations

import json
import socket
import threading
import time
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest

from parsel_litellm import LiteLLMError, LiteLLMProvider

SEED_REPLY = """The top should get wider, so it stretches along x about its centre.

```python
top = part("top")
scale_1d(top, origin=top.center(), dir="x", amount=x)
```
"""


class FakeOpenAI:
    """A chat-completions endpoint that plays a script: statuses, slow replies, then text."""

    def __init__(self) -> None:
        self.script: list[tuple] = []
        self.default = ("reply", "hello")
        self.requests: list[dict] = []
        self.lock = threading.Lock()
        fake = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args) -> None:
                pass

            def do_POST(self) -> None:  # noqa: N802 (http.server's naming)
                length = int(self.headers.get("content-length", 0))
                body = json.loads(self.rfile.read(length) or b"{}")
                with fake.lock:
                    fake.requests.append({"path": self.path, "body": body,
                                          "authorization": self.headers.get("authorization")})
                    action = fake.script.pop(0) if fake.script else fake.default
                kind = action[0]
                if kind == "sleep":
                    time.sleep(action[1])
                    action = ("reply", "too late")
                    kind = "reply"
                if kind == "status":
                    payload = json.dumps({"error": {"message": f"scripted {action[1]}", "type": "scripted"}})
                    self.send_response(action[1])
                    self.send_header("content-type", "application/json")
                    self.send_header("retry-after", "0")
                    self.end_headers()
                    self.wfile.write(payload.encode())
                    return
                text = action[1](body) if callable(action[1]) else action[1]
                payload = json.dumps({
                    "id": "chatcmpl-test", "object": "chat.completion", "created": 0, "model": body.get("model"),
                    "choices": [{"index": 0, "message": {"role": "assistant", "content": text},
                                 "finish_reason": "stop"}],
                    "usage": {"prompt_tokens": 11, "completion_tokens": 7, "total_tokens": 18},
                })
                try:
                    self.send_response(200)
                    self.send_header("content-type", "application/json")
                    self.send_header("content-length", str(len(payload)))
                    self.end_headers()
                    self.wfile.write(payload.encode())
                except (BrokenPipeError, ConnectionResetError):
                    pass

        class Server(ThreadingHTTPServer):
            daemon_threads = True

            def handle_error(self, request, client_address) -> None:
                pass  # a client that gave up on a slow reply is expected here

        self.server = Server(("127.0.0.1", 0), Handler)
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)

    @property
    def base(self) -> str:
        return f"http://127.0.0.1:{self.server.server_address[1]}/v1"

    def __enter__(self) -> FakeOpenAI:
        self.thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.server.shutdown()
        self.server.server_close()


@pytest.fixture
def loopback_only(monkeypatch) -> Iterator[None]:
    """Any attempt to reach a host other than 127.0.0.1 is refused and fails the test
    (recorded too, in case the library swallows the error)."""
    attempts: list[str] = []
    local = ("127.0.0.1", "localhost", "::1", None)
    real_connect = socket.socket.connect
    real_getaddrinfo = socket.getaddrinfo

    def connect(self, address):
        host = address[0] if isinstance(address, tuple) else address
        if host not in local:
            attempts.append(f"connect {address!r}")
            raise OSError(f"test tried to reach {address!r}")
        return real_connect(self, address)

    def getaddrinfo(host, *args, **kwargs):
        if host not in local:
            attempts.append(f"resolve {host!r}")
            raise OSError(f"test tried to resolve {host!r}")
        return real_getaddrinfo(host, *args, **kwargs)

    monkeypatch.setattr(socket.socket, "connect", connect)
    monkeypatch.setattr(socket, "getaddrinfo", getaddrinfo)
    yield
    assert attempts == [], f"network access outside 127.0.0.1: {attempts}"


@pytest.fixture
def fake(loopback_only) -> Iterator[FakeOpenAI]:
    with FakeOpenAI() as server:
        yield server


def options(fake: FakeOpenAI, **extra) -> dict:
    return {"model": "openai/test-model", "api_base": fake.base, "api_key": "sk-test", "timeout": 5,
            "retries": 3, "backoff": 0.01, **extra}


def test_plugin_import_does_not_import_litellm():
    import subprocess
    import sys

    code = "import sys, parsel_litellm; print('litellm' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_litellm_is_told_to_use_its_local_price_list(fake):
    import os

    from parsel_litellm import load_litellm

    load_litellm()
    assert os.environ["LITELLM_LOCAL_MODEL_COST_MAP"] == "True"


def test_sends_the_prompt_and_parses_the_reply(fake):
    fake.script = [("reply", SEED_REPLY)]
    [completion] = LiteLLMProvider().complete("the prompt text", task="seed_edit", **options(fake))
    assert completion.text == SEED_REPLY
    assert (completion.prompt_tokens, completion.completion_tokens) == (11, 7)
    assert completion.meta["attempts"] == 1
    [request] = fake.requests
    assert request["path"].endswith("/chat/completions")
    assert request["body"]["model"] == "test-model"
    assert request["body"]["messages"] == [{"role": "user", "content": "the prompt text"}]
    assert request["authorization"] == "Bearer sk-test"


def test_retries_after_a_429_and_a_500(fake):
    fake.script = [("status", 429), ("status", 500), ("reply", "third time")]
    [completion] = LiteLLMProvider().complete("p", task="seed_edit", **options(fake))
    assert completion.text == "third time"
    assert completion.meta["attempts"] == 3
    assert len(fake.requests) == 3  # no hidden retries inside litellm or the OpenAI client


def test_gives_up_after_the_retries_with_the_status(fake):
    fake.script = [("status", 503)] * 3
    with pytest.raises(LiteLLMError, match=r"failed after 3 attempts \(HTTP 503\)"):
        LiteLLMProvider().complete("p", task="seed_edit", **options(fake, retries=2))
    assert len(fake.requests) == 3


def test_a_bad_request_is_not_retried(fake):
    fake.script = [("status", 401)]
    with pytest.raises(LiteLLMError, match="litellm: openai/test-model at http://127.0.0.1"):
        LiteLLMProvider().complete("p", task="seed_edit", **options(fake))
    assert len(fake.requests) == 1


def test_a_timeout_is_a_clear_error_and_bounded(fake):
    fake.script = [("sleep", 3.0), ("sleep", 3.0)]
    started = time.perf_counter()
    with pytest.raises(LiteLLMError, match=r"timed out after 0.4 s \(2 attempts\)"):
        LiteLLMProvider().complete("p", task="seed_edit", **options(fake, timeout=0.4, retries=1))
    assert time.perf_counter() - started < 2.5


def test_needs_a_model(monkeypatch):
    monkeypatch.delenv("PARSEL_LLM_MODEL", raising=False)
    with pytest.raises(LiteLLMError, match="needs a model"):
        LiteLLMProvider().complete("p", task="seed_edit")


def test_infer_over_http_votes_and_accounts(fake, parsel_shape):
    """The whole language layer over real HTTP: one malformed reply is outvoted, tokens add up."""
    from parsel_core.language import infer

    fake.script = [("reply", SEED_REPLY), ("reply", "scale_1d(top, amount="), ("reply", SEED_REPLY)]
    result = infer(parsel_shape, "make the table wider", provider="litellm", model="openai/test-model",
                   mode="seed-only", samples=3,
                   options={"api_base": fake.base, "api_key": "sk-test", "retries": 0, "workers": 1})
    [op] = result.seed.ops
    assert (op.name, op.operand, op.dir) == ("scale_1d", "top", (1.0, 0.0, 0.0))
    assert result.accounting["calls"] == 3
    assert result.accounting["prompt_tokens"] == 33 and result.accounting["completion_tokens"] == 21
    rejected = [e for e in result.record if e["rejected"]]
    assert len(rejected) == 1 and "malformed" in rejected[0]["rejected"]
    sent = [r["body"]["messages"][0]["content"] for r in fake.requests]
    assert all("<request>make the table wider</request>" in p and '<shape name="tiny_table"' in p for p in sent)
