"""The files a pbrt-v4 scene reads: the root, its Include/Import files and the files its
directives name ("string filename" of plymesh shapes, image textures, lights; "normalmap").
Relative paths resolve against the root file's directory, as lightfarm's parser does. A file
that does not exist is left out: the coordinator then reports the directive's file:line."""

import os

_FILE_PARAMS = {"filename", "normalmap"}


def _tokens(text):
    """pbrt tokens: quoted strings (kept with their quotes), brackets, bare words; # comments."""
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c.isspace():
            i += 1
        elif c == "#":
            while i < n and text[i] not in "\r\n":
                i += 1
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            yield text[i:j + 1]
            i = j + 1
        elif c in "[]":
            yield c
            i += 1
        else:
            j = i
            while j < n and not text[j].isspace() and text[j] not in '"[]#':
                j += 1
            yield text[i:j]
            i = j


def _unquote(tok):
    return tok[1:-1] if len(tok) >= 2 and tok[0] == '"' else None


def scene_files(root):
    """Absolute paths of every file `root` reads, the root first."""
    root = os.path.abspath(root)
    base = os.path.dirname(root)
    out, seen, todo = [], set(), [root]

    def add(path):
        path = os.path.normpath(path if os.path.isabs(path) else os.path.join(base, path))
        if path not in seen and os.path.isfile(path):
            seen.add(path)
            out.append(path)
            return path
        return None

    add(root)
    while todo:
        path = todo.pop(0)
        try:
            with open(path, "r", encoding="utf-8", errors="replace") as f:
                toks = list(_tokens(f.read()))
        except OSError:
            continue
        for k, tok in enumerate(toks):
            nxt = toks[k + 1] if k + 1 < len(toks) else ""
            if tok in ("Include", "Import") and _unquote(nxt) is not None:
                added = add(_unquote(nxt))
                if added:
                    todo.append(added)
                continue
            decl = _unquote(tok)
            if decl is None:
                continue
            parts = decl.split()
            if len(parts) == 2 and parts[0] == "string" and parts[1] in _FILE_PARAMS:
                value = nxt
                if value == "[" and k + 2 < len(toks):
                    value = toks[k + 2]
                if _unquote(value):
                    add(_unquote(value))
    return out
