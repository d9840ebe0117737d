"""Rewrites of a pbrt-v3 scene's options block (stdlib only), shared by the tools that render
the same scene with pbrt-v3 and penumbra: `rewrite` keeps every directive before `WorldBegin`
except the ones it replaces (`Sampler` keeps its type, `Film`, optionally `PixelFilter` and
`Integrator`), so the copy, written beside the original, resolves its relative paths as the
original does.
"""
import re

TOKEN = re.compile(r'"[^"]*"|\[|\]|[^\s\[\]"]+')



def strip_comments(text):
    out = []
    for line in text.splitlines():
        in_str = False
        for i, c in enumerate(line):
            if c == '"':
                in_str = not in_str
            elif c == "#" and not in_str:
                line = line[:i]
                break
        out.append(line)
    return "\n".join(out)


def directives(tokens):
    """Groups tokens into (name, [argument tokens]) in order."""
    out = []
    for t in tokens:
        if t[0].isalpha() and t[0].isupper() and not t.startswith('"'):
            out.append([t, []])
        elif out:
            out[-1][1].append(t)
    return out


def rewrite(text, spp, res, pfm, integrator, box_filter=True):
    """The scene `text` with `Sampler` (its own type) at `spp` samples, `Film` at `res` x `res`
    writing `pfm`, `PixelFilter "box"` when `box_filter`, and, when `integrator` is given, that
    `Integrator`: a name (`path`) or a whole argument list (`"ambientocclusion" "integer nsamples" [ 1 ]`)."""
    head, sep, world = text.partition("WorldBegin")
    assert sep, "no WorldBegin"
    sampler_type = '"halton"'
    kept = []
    for name, args in directives(TOKEN.findall(strip_comments(head))):
        if name == "Sampler":
            sampler_type = args[0]
        elif name == "Integrator" and integrator:
            pass
        elif name == "Film" or (name == "PixelFilter" and box_filter):
            pass
        else:
            kept.append(name + " " + " ".join(args))
    kept.append(f'Sampler {sampler_type} "integer pixelsamples" [ {spp} ]')
    if box_filter:
        kept.append('PixelFilter "box"')
    kept.append(f'Film "image" "integer xresolution" [ {res} ] "integer yresolution" [ {res} ] "string filename" [ "{pfm}" ]')
    if integrator:
        kept.append(f"Integrator {integrator}" if integrator.startswith('"') else f'Integrator "{integrator}"')
    return "\n".join(kept) + "\nWorldBegin" + world


