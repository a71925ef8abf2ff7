"""The shell commands of a Markdown document, as the docs test runs them.

A snippet is a fenced block whose info string is `bash` or `sh`, or one `code` span in the
`command` column of a table. An HTML comment `<!-- docs-test: skip: REASON -->` on the line just
before a block, or in a table row, marks it not to run; the reason is required.
"""
import dataclasses
import re

SHELLS = {"bash", "sh"}
MARKER = re.compile(r"<!--\s*docs-test:\s*(.*?)\s*-->")
FENCE = re.compile(r"^(```+|~~~+)\s*([^\s`]*)")
CODE_SPAN = re.compile(r"`([^`]+)`")


@dataclasses.dataclass
class Snippet:
    line: int  # 1-based line of the block's first command or of the table row
    text: str
    skip: str = ""  # the marker's reason; empty: run it


def marker_reason(comment, where):
    """The reason of a `docs-test: skip: REASON` comment; anything else is an error."""
    match = re.fullmatch(r"skip:\s*(\S.*)", comment)
    if not match:
        raise ValueError(f"{where}: docs-test marker '{comment}' is not 'skip: REASON'")
    return match.group(1)


def split_row(line):
    """A table row's cells, the code spans kept whole (a `|` inside one does not split)."""
    cells, cell, in_code = [], "", False
    for ch in line.strip().strip("|"):
        if ch == "`":
            in_code = not in_code
        if ch == "|" and not in_code:
            cells.append(cell.strip())
            cell = ""
        else:
            cell += ch
    cells.append(cell.strip())
    return cells


def snippets(markdown, name="document"):
    """Every shell snippet of `markdown`, in document order."""
    found, lines = [], markdown.split("\n")
    i, command_column = 0, None
    while i < len(lines):
        line = lines[i]
        fence = FENCE.match(line)
        if fence:
            close = fence.group(1)
            body_start = i + 1
            i += 1
            while i < len(lines) and not lines[i].startswith(close):
                i += 1
            if i == len(lines):
                raise ValueError(f"{name}:{body_start}: code block never closed")
            if fence.group(2) in SHELLS:
                before = MARKER.fullmatch(lines[body_start - 2].strip()) if body_start >= 2 else None
                skip = marker_reason(before.group(1), f"{name}:{body_start - 1}") if before else ""
                found.append(Snippet(body_start + 1, "\n".join(lines[body_start:i]), skip))
            command_column = None
        elif line.startswith("|"):
            cells = split_row(line)
            if command_column is None:
                command_column = cells.index("command") if "command" in cells else -1
            elif command_column >= 0 and not set(line) <= set("|-: "):
                comment = MARKER.search(line)
                skip = marker_reason(comment.group(1), f"{name}:{i + 1}") if comment else ""
                for code in CODE_SPAN.findall(MARKER.sub("", cells[command_column])):
                    found.append(Snippet(i + 1, code, skip))
        else:
            command_column = None
            stray = MARKER.fullmatch(line.strip())
            next_fence = FENCE.match(lines[i + 1]) if i + 1 < len(lines) else None
            if stray and not (next_fence and next_fence.group(2) in SHELLS):
                raise ValueError(f"{name}:{i + 1}: docs-test marker not followed by a bash or sh block")
        i += 1
    return found
