"""The render's console line for report.json says what its real-time factor means."""

from batteur.render import rtf_words


def test_the_real_time_factor_is_said_with_its_meaning() -> None:
    assert rtf_words(0.157) == "real-time factor 0.157: 0.157 s of audio rendered per wall-clock second"
    assert rtf_words(2.4) == "real-time factor 2.4: 2.4 s of audio rendered per wall-clock second"


def test_an_unmeasured_factor_is_said_so() -> None:
    assert rtf_words(None) == "real-time factor not measured"
