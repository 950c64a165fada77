"""The product's surface as a newcomer meets it: README's opening, the size of the source
files, the user documents' links."""

from __future__ import annotations

import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parent.parent
IMAGE = re.compile(r"!\[([^\]]*)\]\(([^)]+)\)")


def test_readme_opening_is_short_and_shows_a_picture_of_a_fit():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    opening = text[: text.index("```sh")]  # everything before the set-up commands
    images = IMAGE.findall(opening)
    assert images, "README shows no picture before the set-up commands"
    for _, target in images:
        assert (ROOT / target).is_file(), target
    words = IMAGE.sub(" ", opening).split()
    assert len(words) <= 200, len(words)
    # The two set-up commands, exactly.
    block = text[text.index("```sh") : text.index("```", text.index("```sh") + 5)]
    commands = [ln.split("#")[0].strip() for ln in block.splitlines()[1:] if ln.strip()]
    assert commands == ["make demo", "make test"], commands


def test_no_source_file_is_over_1200_lines():
    long = {
        str(p.relative_to(ROOT)): n
        for p in (ROOT / "src").rglob("*.rs")
        if (n := len(p.read_text(encoding="utf-8").splitlines())) > 1200
    }
    assert not long, long


def test_user_documents_link_to_files_that_exist_and_not_into_lab_notes():
    docs = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    for doc in docs:
        for target in re.findall(r"\]\(([^)#\s]+)", doc.read_text(encoding="utf-8")):
            if "://" in target:
                continue
            assert (doc.parent / target).exists(), f"{doc.name}: {target}"
            # The main path (README, the guide) never leads into the lab notes.
            assert "notes/" not in target or doc.name not in ("README.md", "guide.md"), (
                f"{doc.name} sends the reader into the lab notes: {target}"
            )
