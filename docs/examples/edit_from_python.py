"""parsel from Python: the whole job in one call, with the offline provider and with your own."""

from parsel_core import edit
from parsel_core.interfaces import Completion, LLMProvider

# 1. A request in words, answered by the offline provider (the default).
result = edit("chair", "make the chair wider")
print(result.program.to_text())
print("relations:", result.report.counts())
print("prompts sent:", result.accounting["calls"], "| stages:", ", ".join(sorted(result.timings)))


# 2. Your own provider object: any class with complete(prompt, *, task, samples, **options).
class Scripted(LLMProvider):
    """Answers every prompt from a table by task; a real one would call a model here."""

    name = "scripted"
    replies = {
        "seed_edit": 'seat = part("seat")\nscale_1d(seat, origin=seat.center(), dir="z", amount=x)',
        "type_hints": "hints = {}",
    }

    def complete(self, prompt, *, task, samples=1, **options):
        text = self.replies.get(task, "valid = True")  # the validity questions: keep every relation
        return [Completion(f"```python\n{text}\n```\n") for _ in range(samples)]


deeper = edit("chair", "make the seat deeper", provider=Scripted())
print(deeper.program.ops[0].name, deeper.program.ops[0].operand, deeper.program.ops[0].dir)
print("relations:", deeper.report.counts())
