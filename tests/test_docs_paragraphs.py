"""The reference docs read as a person reads them (issue 38, item 9): no paragraph of README.md or
of docs/**/*.md runs over 150 words. A paragraph is prose between blank lines outside code
fences (and indented code blocks), tables, headings and HTML comments; each list item is a
paragraph of its own."""
import re

from helpers import pages

LIMIT = 150
FENCE = re.compile(r"^\s*(```|~~~)")
ITEM = re.compile(r"^\s*(?:[-*+]|\d+[.)])\s+")


def paragraphs(text: str):
    """(line, words) of each paragraph of a Markdown page, its first line 1-based."""
    text = re.sub(r"<!--.*?-->", lambda m: "\n" * m.group().count("\n"), text, flags=re.S)
    found, current, start, fence, in_list = [], [], 0, None, False

    def close():
        if current:
            found.append((start, len(" ".join(current).split())))
            current.clear()

    for number, line in enumerate(text.splitlines(), 1):
        opened = FENCE.match(line)
        if fence:
            if opened and opened.group(1) == fence:
                fence = None
            continue
        if opened:
            close()
            fence = opened.group(1)
            continue
        stripped = line.strip()
        if not stripped or stripped.startswith("#") or stripped.startswith("|") or stripped.startswith("!!!"):
            close()  # a blank line, a heading, a table row or an admonition's title line
            continue
        if ITEM.match(line):
            close()
            in_list = True
        elif not current:
            if re.match(r"(?: {4}|\t)", line) and not in_list:
                continue  # an indented code block
            if not line[:1].isspace():
                in_list = False
        if not current:
            start = number
        current.append(re.sub(r"^(?:>\s*)+", "", ITEM.sub("", line).strip()))  # (a list's or a quote's marker is no word)
    close()
    return found


def test_the_paragraph_counter():
    page = "# T\n\none two\nthree\n\n- a b\n  c\n- d\n\n```\n" + "w " * 200 + "\n```\n| x | y |\n<!-- a\nb -->\ne"
    assert paragraphs(page) == [(3, 3), (6, 3), (8, 1), (16, 1)]
    # an indented code block is code; a list item's indented paragraph is prose
    assert paragraphs("a\n\n    code code\n\n- b\n\n    c d\n\ne f") == [(1, 1), (5, 1), (7, 2), (9, 2)]


def test_no_paragraph_runs_over_150_words():
    long = [f"{page}:{line}: {words} words" for page, text in pages().items()
            for line, words in paragraphs(text) if words > LIMIT]
    assert not long, "paragraphs over %d words (split them, a table or a list):\n%s" % (LIMIT, "\n".join(long))
