"""``edc-bench session``: a shift at the bench in one full-screen terminal app.

- :mod:`.scan`: the prompts' fixed order (valve id, pump serial, mount) and what a scanned line means;
- :mod:`.shift`: what the shift did, its summary and the summary's file;
- :mod:`.operator`: the operator's name, asked once and remembered per station;
- :mod:`.runner`: one valve's tests (a MARGINAL's retest included), each with its record, report and history row;
- :mod:`.app`: the Textual app that puts them on the screen.
"""
