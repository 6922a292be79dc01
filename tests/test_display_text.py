"""Program text for people: numbers shortened to the precision that matters, names untouched."""

from __future__ import annotations

from parsel_core.program import Program
from parsel_core.textform import display_text, short_number

NOISY = ("param x in [0.0, 1.0] default 0.5\n"
         "scale_1d(seat, origin=(0.0, 0.4299999922513962, 0.0), dir=(1.0, 0.0, 0.0), amount=x)\n"
         "translate('leg.000', dir=(-1.0, 0.0, 0.0), amount=0.190000005066*x)\n"
         "scale_1d(back_rail, origin=(0.0, 0.830000013113, -0.19), dir=(1.0, 0.0, 0.0), "
         "amount=1.07801415082*x + 0.999999999999*x)\n")


def test_short_numbers():
    assert short_number(0.4299999922513962) == "0.43"  # float32 0.43
    assert short_number(0.999999999999) == "1"
    assert short_number(1.07801415082) == "1.0780142"  # real digits stay (to float32 precision)
    assert short_number(-0.19) == "-0.19" and short_number(2e-20) == "2e-20" and short_number(1234567.0) == "1234567"
    assert short_number(3.14159265358979) == "3.1415927"


def test_display_text_shortens_numbers_but_not_names():
    text = display_text(NOISY)
    assert text == ("param x in [0, 1] default 0.5\n"
                    "scale_1d(seat, origin=(0, 0.43, 0), dir=(1, 0, 0), amount=x)\n"
                    "translate('leg.000', dir=(-1, 0, 0), amount=0.19*x)\n"
                    "scale_1d(back_rail, origin=(0, 0.83, -0.19), dir=(1, 0, 0), amount=1.0780142*x + 1*x)\n")
    shown = Program.from_text(text)  # still a program, equal to the original up to the rounding
    assert len(shown.ops) == 3 and shown.ops[1].operand == "leg.000"
