#!/usr/bin/env python3
"""Regenerates the figures and the two tables of Reeves, Salesin & Cook 1987
("Rendering Antialiased Shadows with Depth Maps") with umbra.

Usage, from anywhere in the checkout:

    python3 scripts/reeves.py [--umbra build/bin/umbra] [--runs 7] [--threads 2]

It renders the scenes of scenes/reeves/ (each uses automatic depth maps) in a
scratch folder and writes:

  docs/figures/reeves_fig05_sphere_plane.png ... the scenes themselves
    (Figures 5, 11, 12, 14);
  docs/figures/reeves_fig06_pcf.png ... reeves_fig10_resolution.png: strips of
    enlarged crops of the sphere-and-plane shadow component, one parameter
    varied per strip (Figures 6 to 10);
  docs/figures/reeves_fig13_depth_maps.png: the desk lamp's three depth maps
    as grey images (nearer is darker, no surface is white);
  docs/reeves-tables.md: Table 1 (time), Table 2 (storage) and the breakdown
    of the desk lamp's extra time, beside the paper's numbers.

Needs python3 (standard library only) and oiiotool (Debian openimageio-tools).
Labels are drawn with DejaVu Sans when fonts-dejavu-core is installed.
"""

import argparse
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = os.path.join(ROOT, "scenes", "reeves")
FIGURES = os.path.join(ROOT, "docs", "figures")
TABLES = os.path.join(ROOT, "docs", "reeves-tables.md")
FONT = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf"

# Scene file, its name in the paper, and the paper's Table 1 and 2 rows:
# (without shadows, lights, first pass, second pass, total, % increase) in
# minutes on a CCI Power 6/32, 1024 pixels wide, 16 samples per pixel; and
# (resolutions, raw, bounding box, tile scheme) in megabytes.
SCENE_ROWS = [
    ("sphere_plane", "Sphere and plane",
     (42.0, 1, 9.7, 48.0, 57.7, 37.3), ("1 at 1024²", 4.0, 0.4, 0.4)),
    ("colored_lights", "Colored lights",
     (64.4, 3, 14.2, 80.8, 95.0, 47.6), ("3 at 1024²", 12.0, 2.6, 2.9)),
    ("desk_lamp", "Luxo Jr. (desk lamp)",
     (58.8, 3, 14.6, 74.2, 88.8, 50.9), ("1 at 2048², 2 at 1024²", 24.0, 13.0, 3.7)),
    ("shop", "Red's Dream (shop)",
     (261.3, 2, 55.3, 332.1, 387.4, 48.4), ("2 at 1024²", 8.0, 5.6, 4.2)),
]
# Storage targets (tile scheme as a share of raw) where the brief sets one.
STORAGE_TARGET = {"sphere_plane": 10.0, "desk_lamp": 16.0}

# The crop of the 640x480 sphere-and-plane image that the parameter strips
# show: the sphere's terminator and the shadow's edge on the ground.
CROP = "200x150+290+190"
ZOOM = "400x300"


def run(cmd, cwd=None, quiet=False):
    """Runs a command; stops the script with its output if it fails."""
    r = subprocess.run(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if r.returncode != 0:
        sys.stderr.write(f"reeves.py: {' '.join(cmd)} failed ({r.returncode}):\n{r.stdout}{r.stderr}")
        sys.exit(1)
    if r.stderr and not quiet:
        sys.stderr.write(r.stderr)
    return r.stdout


def light_statement(text, handle):
    """The (start, end) span of the LightSource request with this handle."""
    m = re.search(r'LightSource\s+"[^"]+"\s+"%s"' % re.escape(handle), text)
    if not m:
        raise KeyError(f"no LightSource with handle {handle!r}")
    end = m.end()
    # A RIB request continues until the next line that starts a new request.
    nxt = re.compile(r"\n\s*(?=[A-Z#]|$)")
    n = nxt.search(text, end)
    return m.start(), (n.start() if n else len(text))


def set_light_params(text, handle, params):
    """Sets (replacing or appending) parameters of one light's request.
    Values are floats or strings."""
    start, end = light_statement(text, handle)
    stmt = text[start:end]
    for name, value in params.items():
        rib = f'["{value}"]' if isinstance(value, str) else f"[{value:g}]"
        pat = re.compile(r'"%s"\s*\[[^\]]*\]' % re.escape(name))
        if pat.search(stmt):
            stmt = pat.sub(lambda _m: f'"{name}" {rib}', stmt, count=1)
        else:
            stmt += f' "{name}" {rib}'
    return text[:start] + stmt + text[end:]


def set_option(text, option_line):
    """Inserts a request line before WorldBegin (options apply to the frame)."""
    return text.replace("WorldBegin", option_line + "\nWorldBegin", 1)


def set_display(text, image):
    return re.sub(r'Display\s+"[^"]+"', f'Display "{image}"', text, count=1)


class Renderer:
    """Renders RIB text with umbra in a scratch folder holding scenes/reeves."""

    def __init__(self, umbra, work, threads):
        self.umbra, self.work, self.threads = umbra, work, threads

    def render(self, name, text, no_shadows=False):
        """Renders `text` as <name>.rib; returns the frame's statistics."""
        rib = os.path.join(self.work, name + ".rib")
        with open(rib, "w") as f:
            f.write(set_display(text, name + ".tif"))
        stats = os.path.join(self.work, name + ".json")
        cmd = [self.umbra, "render", "--quiet", "--threads", str(self.threads), "--stats", stats]
        if no_shadows:
            cmd.append("--no-shadows")
        run(cmd + [name + ".rib"], cwd=self.work)
        with open(stats) as f:
            return json.load(f)["frames"][0]

    def image(self, name):
        return os.path.join(self.work, name + ".tif")

    def info(self, path):
        return json.loads(run([self.umbra, "info", "--json", path], cwd=self.work))


def label_args(text, size=13):
    if not os.path.exists(FONT):
        return []
    return [f"--text:x=8:y={size + 6}:size={size}:color=1,0.85,0.1:font={FONT}", text]


def crop_tile(src, out, label, crop=CROP):
    """An enlarged (pixel-replicated, as the paper's zooms) crop, labelled."""
    run(["oiiotool", src, "--ch", "R,G,B", "--cut", crop, "--resample", ZOOM] + label_args(label) + ["-o", out])


def strip(tiles, out):
    run(["oiiotool"] + tiles + ["--mosaic:pad=6", f"{len(tiles)}x1", "-o", out])


def read_scene(name):
    with open(os.path.join(SCENES, name + ".rib")) as f:
        return f.read()


def shadow_component(text):
    """Reeves Figure 6: every surface shows only the light reaching it."""
    text = re.sub(r'Surface\s+"[a-z]+"[^\n]*', 'Surface "shadowmatte"', text)
    text = set_light_params(text, "key", {"shadowonly": 1})
    return re.sub(r'LightSource "ambientlight" 1 "intensity" \[[^\]]*\]',
                  'LightSource "ambientlight" 1 "intensity" [0]', text)


def parameter_figures(r):
    """Figures 6-10 on the sphere-and-plane scene (about 100 units across, like
    the paper's worlds, so its bias values are used unscaled)."""
    base = shadow_component(read_scene("sphere_plane"))
    # The paper's defaults (NumSamples 16, ResFactor 3, MinSamples 2, MinSize
    # 2, jittered sampling) and the scene's bias (0.6, 0.9): the paper's
    # (0.3, 0.4) was for 1024-texel maps, these are 640 wide (1.6x coarser).
    defaults = {"samples": 16, "width": 3, "bias0": 0.6, "bias1": 0.9, "minsamples": 2, "minsize": 2,
                "sampling": "jittered"}
    figures = [
        ("reeves_fig06_pcf", [
            # The region shrunk to a point: one unjittered depth comparison
            # at the shading point, Williams' ordinary z-buffer algorithm.
            ("a: point sampled (samples 1, region a point)",
             {"samples": 1, "width": 0.01, "minsize": 0.01, "minsamples": 1}, None),
            ("b: percentage closer (samples 16, width 1)", {"samples": 16, "width": 1}, None)]),
        ("reeves_fig07_samples", [
            (f"NumSamples {n}", {"samples": n}, None) for n in (1, 4, 16)]),
        ("reeves_fig08_width", [
            (f"ResFactor (width) {w}", {"width": w}, None) for w in (1, 3, 8)]),
        ("reeves_fig09_bias", [
            # umbra substitutes its default bias (0.225) when all biases are
            # 0, so "no bias" is asked for as the range [0, 1e-6].
            (f"bias ({b0:g}, {b1:g})", {"bias0": b0, "bias1": b1 or 1e-6}, None)
            for b0, b1 in ((0, 0), (0.2, 0.3), (0.3, 0.4), (0.6, 0.9))]),
        ("reeves_fig10_resolution", [
            (f"map {n}x{n}", {}, n) for n in (256, 512, 1024)]),
    ]
    for fig, cases in figures:
        tiles = []
        for k, (label, params, mapsize) in enumerate(cases):
            text = set_light_params(base, "key", dict(defaults, **params))
            if mapsize:
                text = re.sub(r'Option "umbra" "shadowmapsize" \[\d+\]',
                              f'Option "umbra" "shadowmapsize" [{mapsize}]', text)
            name = f"{fig}_{k}"
            r.render(name, text)
            tile = os.path.join(r.work, name + ".png")
            crop_tile(r.image(name), tile, label)
            tiles.append(tile)
        out = os.path.join(FIGURES, fig + ".png")
        strip(tiles, out)
        print(f"wrote {os.path.relpath(out, ROOT)}")


def scene_figures(r):
    """Figures 5, 11, 12 and 14: the scenes as they are."""
    for fig, name in (("05", "sphere_plane"), ("11", "colored_lights"), ("12", "desk_lamp"), ("14", "shop")):
        r.render(name, read_scene(name))
        out = os.path.join(FIGURES, f"reeves_fig{fig}_{name}.png")
        run(["oiiotool", r.image(name), "--ch", "R,G,B", "-o", out])
        print(f"wrote {os.path.relpath(out, ROOT)}")


def depth_map_figure(r):
    """Figure 13: the desk lamp's depth maps, light-space z as grey (nearer is
    darker; pixels with no surface, +inf or outside the stored bounding box,
    white). The scene must have been rendered by scene_figures."""
    tiles = []
    for handle in ("dad", "junior", "ceiling"):
        path = os.path.join(r.work, f"desk_lamp.{handle}.shd")
        info = r.info(path)
        lo, hi = info.get("minZ", 0), info.get("maxZ", 1)
        scale = 0.8 / max(hi - lo, 1e-6)
        tile = os.path.join(r.work, f"map_{handle}.png")
        # grey = 0.05 + 0.8 (z - min) / (max - min), +inf clamps to 1. The
        # value is inverted around the padding to the full map so that the
        # padding (filled with 0) comes out white too.
        run(["oiiotool", path, "--ch", "Z", "--subc", f"{lo}", "--mulc", f"{scale}", "--addc", "0.05",
             "--clamp:min=0:max=1", "--invert:chbegin=0:chend=1", "--croptofull",
             "--invert:chbegin=0:chend=1", "--ch", "R=Z,G=Z,B=Z",
             "--resize", "320x320"] + label_args(f"{handle} ({info['width']}x{info['height']})")
            + ["-o", tile])
        tiles.append(tile)
    out = os.path.join(FIGURES, "reeves_fig13_depth_maps.png")
    strip(tiles, out)
    print(f"wrote {os.path.relpath(out, ROOT)}")


def best_pair(r, name, text, runs):
    """The statistics of the fastest of `runs` renders without and with
    shadows (by frame wall time), the two alternating so that a slow period
    of the machine weighs on both sides of the ratio alike."""
    best = {True: None, False: None}
    for k in range(runs):
        for no_shadows in (True, False):
            f = r.render(f"time_{name}_{'ns' if no_shadows else 'sh'}", text, no_shadows)
            if best[no_shadows] is None or f["wall_seconds"] < best[no_shadows]["wall_seconds"]:
                best[no_shadows] = f
    return best[True], best[False]


def machine():
    cpu = platform.processor() or "unknown CPU"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    osname = platform.system()
    try:
        with open("/etc/os-release") as f:
            for line in f:
                if line.startswith("PRETTY_NAME="):
                    osname = line.split("=", 1)[1].strip().strip('"')
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} logical CPUs, {osname}"


def mb(n):
    return n / 1e6


def tables(r, runs, threads):
    """Table 1 and 2 rows: (key, label, figures..., paper figures, has a target)."""
    rows1, rows2, lamp = [], [], None
    for name, label, paper1, paper2 in SCENE_ROWS:
        ns, sh = best_pair(r, name, read_scene(name), runs)
        depth = [p for p in sh["passes"] if p["name"].startswith("depth:")]
        first = sh["first_pass"]["wall_seconds"]  # the lights' passes overlap
        total = sh["wall_seconds"]
        second = total - first
        without = ns["wall_seconds"]
        increase = 100 * (total - without) / without
        rows1.append((label, without, len(depth), first, second, total, increase, paper1))
        raw = bbox = tiles = disk = 0
        resolutions = []
        for p in depth:
            handle = p["name"].split(":", 1)[1]
            info = r.info(os.path.join(r.work, f"time_{name}_sh.{handle}.shd"))
            s = info["storage"]
            raw += s["rawBytes"]
            bbox += s["bboxBytes"]
            tiles += s["tileBytes"]
            disk += s["fileBytes"]
            resolutions.append(f"{info['width']}²")
        rows2.append((name, label, resolutions, raw, bbox, tiles, disk, paper2))
        if name == "desk_lamp":
            lamp = (ns, sh)
    return rows1, rows2, lamp


def write_tables(rows1, rows2, lamp, runs, threads, umbra):
    out = []
    w = out.append
    w("# Reeves, Salesin & Cook 1987, Tables 1 and 2, measured with umbra\n")
    w(f"Generated by `python3 scripts/reeves.py` on {time.strftime('%Y-%m-%d')}; do not edit by hand.\n")
    w(f"Machine: {machine()}. Renderer: `{os.path.relpath(umbra, ROOT)}`, "
      f"`--threads {threads}`, best of {runs} runs per configuration. Scenes: `scenes/reeves/*.rib`, "
      "640x480, `PixelSamples 4 4` (16 samples per pixel, as the paper), automatic depth maps at 640x640 "
      "(the desk lamp's ceiling light at 1280x1280, as the paper's mix of sizes), "
      "16 samples per `shadow()` lookup. The paper's times are minutes on a CCI Power 6/32 at 1024 pixels "
      "wide; only the ratios compare.\n")
    w("## Table 1: shadow algorithm performance\n")
    w("Seconds of frame wall time (`frames[0].wall_seconds` of `--stats`). *Without shadows* is the same "
      "scene rendered with `--no-shadows`; *first pass* is the making of every depth map (`first_pass`: the "
      "lights' depth passes run side by side, then each map is built and its file written in the "
      "background); *second "
      "pass* is the rest of the shadowed frame (camera pass and output); *total* is the shadowed frame. "
      "Target: at most half of the paper's % increase on every row.\n")
    w("| image | without shadows (s) | lights | first pass (s) | second pass (s) | total (s) | % increase "
      "| paper: without / first / second / total (min) | paper % increase | target | met |")
    w("|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---|")
    all_met = True
    for name, without, lights, first, second, total, inc, p in rows1:
        target = p[5] / 2
        met = inc <= target
        all_met &= met
        verdict = "yes" if met else "**no**"
        w(f"| {name} | {without:.3f} | {lights} | {first:.3f} | {second:.3f} | {total:.3f} | {inc:.1f} "
          f"| {p[0]} / {p[2]} / {p[3]} / {p[4]} | {p[5]} | ≤ {target:.1f} | {verdict} |")
    w("")
    w(f"**Time target {'met' if all_met else 'NOT met'}** on {'every row' if all_met else 'the rows marked no'}.\n")

    w("## Table 2: depth map storage\n")
    w("Megabytes (10⁶ bytes), summed over the scene's maps, from `umbra info --json`: *raw* is width x "
      "height x 4 bytes; *bounding box* stores only the box of finite depths (Reeves §3.3); *tile scheme* "
      "stores only the 32x32 tiles holding a finite depth (4 KiB each, uncompressed); *on disk* is the "
      "zip-compressed tiled OpenEXR file umbra writes.\n")
    w("| image | maps | raw | bounding box | tile scheme | tile % of raw | on disk | paper: maps | "
      "paper: raw / bbox / tile | paper tile % | target | met |")
    w("|---|---|---:|---:|---:|---:|---:|---|---|---:|---:|---|")
    storage_met = True
    for key, name, res, raw, bbox, tiles, disk, p in rows2:
        pct = 100 * tiles / raw if raw else 0
        target = STORAGE_TARGET.get(key)
        met = "" if target is None else ("yes" if pct <= target else "**no**")
        if target is not None and pct > target:
            storage_met = False
        sizes = ", ".join(f"{res.count(size)} at {size}" for size in sorted(set(res), key=lambda t: -int(t[:-1])))
        w(f"| {name} | {sizes} | {mb(raw):.2f} | {mb(bbox):.2f} "
          f"({100 * bbox / raw:.1f}%) | {mb(tiles):.2f} | {pct:.1f} | {mb(disk):.3f} | {p[0]} | "
          f"{p[1]} / {p[2]} / {p[3]} | {100 * p[3] / p[1]:.1f} | {'≤ %g' % target if target else '—'} | {met} |")
    w("")
    w(f"**Storage target {'met' if storage_met else 'NOT met'}** (tile scheme ≤ 10% of raw for the sphere "
      "and plane, ≤ 16% for the desk lamp).\n")
    w("The desk lamp has the paper's mix of map sizes: its ceiling light's map is twice the others' size "
      "(`Attribute \"umbra\" \"shadowmapsize\"` on that light), as Luxo Jr. had one map at 2048² and two at "
      "1024². That map holds the few texels the distant lamps cover, so it adds more raw bytes than tiles.\n")

    ns, sh = lamp
    w("## Where the desk lamp's extra time goes\n")
    w("The paper's Luxo Jr. frame: first pass 50% of the extra time, percentage closer filtering 28%, the "
      "light trees' (interpreted) transformation into light space 22%. umbra's split, in CPU seconds summed "
      "over threads (`cpu_seconds` of the frame, `worker_cpu_seconds` of the depth passes, "
      "`shadow.map_file_cpu_seconds`, `shading.seconds`, `shadow.lookup_seconds`): *map files* is encoding "
      "and writing the three maps' OpenEXR files (in the background, while later passes run); "
      "*interpreter* is the growth of the time inside the shading VM minus the lookups it made; *other* is "
      "what remains (bucketing, scheduling, noise between runs).\n")
    extra = sh["cpu_seconds"] - ns["cpu_seconds"]
    first = sum(p["worker_cpu_seconds"] for p in sh["passes"] if p["name"].startswith("depth:"))
    files = sh["shadow"]["map_file_cpu_seconds"]
    lookup = sh["shadow"].get("lookup_seconds", 0.0)
    interp = sh["shading"]["seconds"] - ns["shading"]["seconds"] - lookup
    other = extra - first - files - lookup - interp
    w("| part | CPU seconds | share of extra | paper share |")
    w("|---|---:|---:|---:|")
    for label, v, paper in (("first pass (3 depth maps)", first, "50%"),
                            ("map files (OpenEXR, zip)", files, "—"),
                            ("percentage closer filtering", lookup, "28%"),
                            ("interpreter (light shaders, transformation)", interp, "22%"),
                            ("other", other, "—")):
        share = f"{100 * v / extra:.0f}%" if extra > 0 else "—"
        w(f"| {label} | {v:.4f} | {share} | {paper} |")
    w(f"| **extra CPU time** | {extra:.4f} | 100% | 100% |")
    w("")
    s = sh["shadow"]
    w(f"Lookups in the shadowed desk-lamp frame: {s['points']} points, {s['outside']} outside a map, "
      f"{s['culled_lit']} culled lit and {s['culled_shadowed']} culled shadowed by the per-tile depth range, "
      f"{s['filtered']} filtered with {s['samples']} texel comparisons "
      f"({s['samples'] / max(s['filtered'], 1):.1f} per filtered point).\n")
    with open(TABLES, "w") as f:
        f.write("\n".join(out))
    print(f"wrote {os.path.relpath(TABLES, ROOT)}")
    return all_met, storage_met


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--umbra", default=os.path.join(ROOT, "build", "bin", "umbra"),
                    help="the umbra binary (default: build/bin/umbra)")
    ap.add_argument("--runs", type=int, default=7, help="timing runs per configuration; the best counts")
    ap.add_argument("--threads", type=int, default=2, help="render threads for every render")
    ap.add_argument("--keep", action="store_true", help="keep the scratch folder and print its path")
    args = ap.parse_args()
    umbra = os.path.abspath(args.umbra)
    if not os.access(umbra, os.X_OK):
        sys.exit(f"reeves.py: {umbra} is not an executable umbra binary (build it, or pass --umbra)")
    if not shutil.which("oiiotool"):
        sys.exit("reeves.py: oiiotool not found (apt-get install openimageio-tools)")
    os.makedirs(FIGURES, exist_ok=True)
    work = tempfile.mkdtemp(prefix="umbra-reeves-")
    try:
        shutil.copytree(os.path.join(SCENES, "shaders"), os.path.join(work, "shaders"))
        r = Renderer(umbra, work, args.threads)
        scene_figures(r)
        depth_map_figure(r)
        parameter_figures(r)
        rows1, rows2, lamp = tables(r, args.runs, args.threads)
        write_tables(rows1, rows2, lamp, args.runs, args.threads, umbra)
    finally:
        if args.keep:
            print(f"scratch folder: {work}")
        else:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
