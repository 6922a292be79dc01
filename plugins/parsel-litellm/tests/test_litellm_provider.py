"""The litellm provider against a fake OpenAI-compatible server on 127.0.0.1.

No test reaches beyond the loopback interface: a guard makes any other connection an
error, and litellm is told to use its bundled price list before it is imported.
"""

from __future__ import annotations

import json
import math
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


def test_plugin_import_does_not_import_litellm(parsel_fresh_python):
    code = "import sys, parsel_litellm; print('litellm' in sys.modules)"
    assert parsel_fresh_python(code).strip() == "False"


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


# -- the model path: amounts, fail-fast, code blocks, pictures (issue: fail fast and safely) ------------


def _seed_only(fake, shape, request="make the table wider", samples=1, **extra):
    from parsel_core.language import infer

    return infer(shape, request, provider="litellm", model="openai/test-model", mode="seed-only", samples=samples,
                 options={"api_base": fake.base, "api_key": "sk-test", "retries": 0, "workers": 1, **extra})


def _rotate_reply(amount: str) -> str:
    return f"""Turn the top about the vertical.

```python
top = part("top")
rotate(top, origin=top.center(), axis="y", amount={amount})
```
"""


@pytest.mark.parametrize("amount", ["-15 * x", "90 * x", "\"45 * x\""])
def test_rotation_amounts_in_degrees_are_rejected_with_a_reason(fake, parsel_shape, amount):
    from parsel_core.language import InferenceError

    fake.default = ("reply", _rotate_reply(amount))
    with pytest.raises(InferenceError, match="more than a full turn; if it is in degrees write radians"):
        _seed_only(fake, parsel_shape)


@pytest.mark.parametrize("amount, radians", [("radians(15) * x", 15 * math.pi / 180), ("pi / 12 * x", math.pi / 12),
                                             ("-radians(90) * x", -math.pi / 2), ("2 * pi * x", 2 * math.pi)])
def test_rotation_amounts_in_radians_are_accepted(fake, parsel_shape, amount, radians):
    from parsel_core.language.amounts import amount_values

    fake.default = ("reply", _rotate_reply(amount))
    [op] = _seed_only(fake, parsel_shape).seed.ops
    assert "radians" not in op.amount
    assert amount_values(op.amount, "x", 0, 1, samples=2)[1] == pytest.approx(radians)


@pytest.mark.parametrize("amount, why", [
    ("x / 0", "division by zero"), ("log(0) + x", "log"), ("sqrt(-1) * x", "sqrt"),
    ("9**9**9**9 * x", "x = 0"), ("1e300 * x", "beyond"), ("x**-1", "at x = 0"), ("(x - 0.5)**-1", "at x = 0.5"),
    ("exp(1000 * x)", "exp"), ("1e200 * x * 1e200", "at x = "),
])
def test_amounts_without_a_finite_value_are_rejected_per_sample(fake, parsel_shape, amount, why):
    """Each bad amount is a rejected sample with a reason, never a traceback nor a kept report with NaN."""
    from parsel_core.language import InferenceError

    reply = SEED_REPLY.replace("amount=x", f"amount={amount}")
    fake.script = [("reply", reply), ("reply", SEED_REPLY), ("reply", reply)]
    with pytest.raises(InferenceError) as caught:
        _seed_only(fake, parsel_shape, samples=1)
    [entry] = caught.value.record
    assert "is not a finite number" in entry["rejected"] and why in entry["rejected"]
    # One good sample among bad ones wins the vote: rejection is per sample.
    fake.script = [("reply", reply), ("reply", SEED_REPLY), ("reply", reply)]
    result = _seed_only(fake, parsel_shape, samples=3)
    assert [op.amount for op in result.seed.ops] == ["x"]
    assert sum(1 for e in result.record if e["rejected"]) == 2


@pytest.mark.parametrize("status", [400, 401, 404])
def test_a_bad_key_or_request_stops_after_the_first_call(fake, parsel_shape, status):
    from parsel_core.language import InferenceError, infer

    fake.default = ("status", status)
    started = time.perf_counter()
    with pytest.raises(InferenceError) as caught:
        infer(parsel_shape, "make the table wider", provider="litellm", model="openai/test-model", samples=5,
              options={"api_base": fake.base, "api_key": "sk-test", "retries": 3, "backoff": 0.01})
    message = str(caught.value)
    assert len(fake.requests) == 1, "one call, not one per prompt and sample"
    assert message.startswith("provider 'litellm' failed: litellm: openai/test-model")
    total = len(caught.value.record)
    assert f"({total - 1} further calls not sent)" in message and "\n" not in message
    assert caught.value.accounting["calls"] == 1 and caught.value.accounting["skipped"] == total - 1
    assert time.perf_counter() - started < 5


def test_a_missing_model_is_one_message(parsel_shape, monkeypatch):
    from parsel_core.language import InferenceError, infer

    monkeypatch.delenv("PARSEL_LLM_MODEL", raising=False)
    with pytest.raises(InferenceError, match=r"needs a model.*further calls not sent\)$") as caught:
        infer(parsel_shape, "make the table wider", provider="litellm", samples=5)
    assert sum(1 for e in caught.value.record if not e.get("skipped")) == 1


def test_a_missing_key_is_one_message(loopback_only, parsel_shape, monkeypatch):
    from parsel_core.language import InferenceError, infer

    for name in ("OPENAI_API_KEY", "PARSEL_LLM_API_KEY"):
        monkeypatch.delenv(name, raising=False)
    with pytest.raises(InferenceError, match="provider 'litellm' failed: .*api_key") as caught:
        infer(parsel_shape, "make the table wider", provider="litellm", model="openai/gpt-4o", samples=3,
              options={"retries": 2, "backoff": 0.01})
    assert sum(1 for e in caught.value.record if not e.get("skipped")) == 1


def test_a_hung_server_costs_at_most_timeout_times_attempts(fake, parsel_shape):
    """Worst case: (retries + 1) * timeout + the backoffs for the first call; the rest are not sent."""
    from parsel_core.language import InferenceError, infer

    fake.default = ("sleep", 5.0)
    started = time.perf_counter()
    with pytest.raises(InferenceError, match=r"timed out after 0.3 s \(2 attempts\)"):
        infer(parsel_shape, "make the table wider", provider="litellm", model="openai/test-model", samples=5,
              options={"api_base": fake.base, "api_key": "sk-test", "timeout": 0.3, "retries": 1, "backoff": 0.01})
    elapsed = time.perf_counter() - started
    assert len(fake.requests) == 2
    assert elapsed < 2 * 0.3 + 1.5


def test_the_code_block_that_parses_is_the_answer_and_the_record_says_which(fake, parsel_shape):
    example_first = ("The API looks like this:\n\n```\nscale_1d(target, origin=..., dir=..., amount=...)\n```\n\n"
                     "For this shape:\n\n" + SEED_REPLY.split("\n\n", 1)[1])
    answer_first = SEED_REPLY + "\nOther edits could be:\n\n```python\nrotate(top, axis=\"y\")\n```\n"
    fake.script = [("reply", example_first), ("reply", answer_first)]
    result = _seed_only(fake, parsel_shape, samples=2)
    assert [op.name for op in result.seed.ops] == ["scale_1d"]
    assert [e["code_block"] for e in result.record] == ["2 of 2", "1 of 2"]
    assert result.votes["seed_edit"]["valid"] == 2


def test_with_image_sends_an_image_part_and_records_its_hash(fake, tmp_path):
    import base64
    import hashlib
    import struct

    from parsel_core.cli import main

    fake.default = ("reply", SEED_REPLY)
    out = tmp_path / "out"
    assert main(["edit", "tiny_table", "make the table wider", "--provider", "litellm", "--model",
                 "openai/test-model", "--api-base", fake.base, "--samples", "1", "--mode", "seed-only",
                 "--with-image", "--retries", "0", "--timeout", "10", "-o", str(out)]) == 0
    [request] = fake.requests
    [message] = request["body"]["messages"]
    text, image = message["content"]
    assert text["type"] == "text" and "A picture of the shape is attached" in text["text"]
    assert image["type"] == "image_url"
    header, data = image["image_url"]["url"].split(",", 1)
    assert header == "data:image/png;base64"
    png = base64.b64decode(data)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert struct.unpack(">II", png[16:24]) == (512, 512), "IHDR: width, height"
    assert 5_000 < len(png) < 400_000
    [entry] = [json.loads(line) for line in (out / "record.jsonl").read_text().splitlines()]
    assert entry["image_sha256"] == hashlib.sha256(png).hexdigest()
    assert "A picture of the shape is attached" in entry["prompt"]


def test_with_image_is_refused_for_a_text_only_model_before_any_call(loopback_only, parsel_shape):
    from parsel_core.language import InferenceError, infer

    with pytest.raises(InferenceError, match="does not take images"):
        infer(parsel_shape, "make the table wider", provider="litellm", model="gpt-3.5-turbo", samples=2,
              mode="seed-only", options={"api_key": "sk-test", "image": b"\x89PNG fake", "retries": 0})


def test_timeout_and_retries_flags_bound_a_hung_server(fake, tmp_path, capsys):
    from parsel_core.cli import main

    fake.default = ("sleep", 5.0)
    started = time.perf_counter()
    assert main(["edit", "tiny_table", "make the table wider", "--provider", "litellm", "--model",
                 "openai/test-model", "--api-base", fake.base, "--timeout", "0.3", "--retries", "0",
                 "-o", str(tmp_path / "out")]) == 2
    assert time.perf_counter() - started < 2.0
    assert len(fake.requests) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "timed out after 0.3 s (1 attempt)" in err


def test_a_failed_model_run_keeps_the_previous_outdir(fake, tmp_path, capsys):
    from parsel_core.cli import main

    out = tmp_path / "out"
    base = ["edit", "tiny_table", "make the table wider", "--provider", "litellm", "--model", "openai/test-model",
            "--api-base", fake.base, "--mode", "seed-only", "--samples", "1", "--retries", "0", "-o", str(out)]
    fake.default = ("reply", SEED_REPLY)
    assert main(base) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    fake.default = ("status", 401)
    capsys.readouterr()
    assert main(base) == 2
    err = capsys.readouterr().err
    assert f"{out} is kept as it was; the record of this run is in {out}.failed-record.jsonl" in err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    [entry] = [json.loads(line) for line in (tmp_path / "out.failed-record.jsonl").read_text().splitlines()]
    assert "401" in entry["error"]


def test_a_model_record_replayed_for_another_request_fails(fake, parsel_shape, tmp_path):
    from parsel_core.language import InferenceError, infer

    fake.default = ("reply", SEED_REPLY)
    record = _seed_only(fake, parsel_shape, "make the table wider", samples=2).record
    path = tmp_path / "record.jsonl"
    path.write_text("".join(json.dumps(e) + "\n" for e in record), encoding="utf-8")
    again = infer(parsel_shape, "make the table wider", provider="replay", mode="seed-only", samples=2,
                  options={"replay": str(path)})
    assert [op.operand for op in again.seed.ops] == ["top"]
    with pytest.raises(InferenceError, match="answers request 'make the table wider', not 'make the legs longer'"):
        infer(parsel_shape, "make the legs longer", provider="replay", mode="seed-only", samples=2,
              options={"replay": str(path)})
