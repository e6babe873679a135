"""``treeform`` command: thin handlers over the Python API."""

from __future__ import annotations

import sys
from enum import Enum
from pathlib import Path
from typing import Optional

import typer

from treeform._shared.defaults import DEFAULT_SEGMENTER
from treeform import __version__
from treeform._shared.errors import TreeformError

def _plain_help() -> None:
    """Usage lines and option tables in the familiar form on every typer version.

    Recent typer prints required arguments as ``{PHOTO}`` in usage lines and a ``<bool>``
    type beside every flag, ``--help`` included; users read ``PHOTO`` and a bare flag. Both
    hooks are optional: on versions without them nothing changes.
    """
    from typer import core

    arg = getattr(core, "TyperArgument", None)
    if arg is not None and hasattr(arg, "_usage_display_name"):
        def _usage_name(self, _orig=arg._usage_display_name):
            name = _orig(self)
            return name[1:-1] if name.startswith("{") and name.endswith("}") else name
        arg._usage_display_name = _usage_name
    opt = getattr(core, "TyperOption", None)
    if opt is not None and hasattr(opt, "display_type_rich"):
        def _type_label(self, ctx, _orig=opt.display_type_rich):
            return None if getattr(self, "is_bool_flag", False) else _orig(self, ctx)
        opt.display_type_rich = _type_label


_plain_help()

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="treeform: photographs of real trees -> 3D tree assets.")


def _choices(name: str, *values: str) -> type:
    """A ``str`` Enum whose members are named by their values (what typer shows as choices)."""
    return Enum(name, [(v, v) for v in values], type=str)


Crown = _choices("Crown", "auto", "round", "conical")
Form = _choices("Form", "auto", "broadleaf", "conifer")
SegmenterName = _choices("SegmenterName", "learned", "classical")
FeetSource = _choices("FeetSource", "rules", "learned", "both")
SEGMENTER_OPTION = typer.Option(SegmenterName(DEFAULT_SEGMENTER), "--segmenter",
                                help=f"Tree segmentation: 'classical' (colour rules + graph cut) or 'learned' (network); "
                                     f"default {DEFAULT_SEGMENTER}.")


Lod = _choices("Lod", "low", "medium", "high", "full")
FoliageKind = _choices("FoliageKind", "auto", "broadleaf", "needles", "scales")


def seed_option(help: str = "Random seed."):
    """The ``--seed`` option of every command: an integer in [0, MAX_SEED], checked before anything runs."""
    from treeform._shared.rng import MAX_SEED

    return typer.Option(0, "--seed", min=0, max=MAX_SEED, help=help)


TEXTURE_SIZE_HELP = "Bark texture edge in texels, leaves half of it (default: from the tree's size, >= 512/256)."


def _version(value: bool):
    if value:
        typer.echo(f"treeform {__version__}")
        raise typer.Exit()


@app.callback()
def _main(version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                       help="Print the version and exit.")):
    """treeform: photographs of real trees -> 3D tree assets."""


def _fail(message: str, code: int):
    """The one ``error:`` line on stderr (after any progress display is closed), then exit ``code``."""
    sys.stdout.flush()
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(code)


def run_api(func, *args, stages=None, display=None, inputs=(), **kwargs):
    """Run an API call with a progress display; TreeformError -> one line, non-zero exit.

    ``func`` must accept ``progress=callback(stage, event, seconds)``; ``stages`` names its
    stages (for the bar's total; default: the single-photo pipeline's). ``display`` replaces
    the stage bar by another context manager with a ``callback`` (e.g. a
    :class:`~treeform.cli.progress.CountProgress` for ``progress(done, total)``).
    ``inputs``: the command's input paths (or ``(label, path)`` pairs, None for an option not
    given), checked all at once before anything starts, so every missing one is named.

    The display is closed (a terminal's unfinished bar erased) before the error line is
    printed, so ``error: ...`` is always the last line, on its own.
    """
    from treeform._shared.checks import check_inputs_exist
    from treeform.cli.progress import StageProgress

    try:
        check_inputs_exist(inputs)
    except TreeformError as exc:
        _fail(str(exc), exc.exit_code)
    if display is None:
        display = StageProgress(stages) if stages else StageProgress()
    try:
        with display as prog:
            return func(*args, progress=prog.callback, **kwargs)
    except TreeformError as exc:
        _fail(str(exc), exc.exit_code)
    except MemoryError:
        _fail("out of memory (try a smaller --lod or photo)", 1)


LeafTexture = _choices("LeafTexture", "photo", "procedural")
LeafPlacement = _choices("LeafPlacement", "surface", "segments")
HiddenGrowth = _choices("HiddenGrowth", "replication", "colonization")
Profile = _choices("Profile", "rounded", "thin-plate")
Colonization = _choices("Colonization", "coarse", "paper")
Method = _choices("Method", "envelope", "learned", "abs")
IMPOSTOR_HELP = ("Also write impostor/: the colour cubemap, radial distance map and leaflet billboard for drawing "
                 "the tree at distance (as `treeform impostor`).")


@app.command()
def reconstruct(
    photo: Path = typer.Argument(..., metavar="PHOTO", help="Photo of a tree (JPEG, PNG, ...), or a cut-out "
                                 "(RGBA PNG / WebP: its alpha is the tree mask, no segmentation)."),
    method: Method = typer.Option(Method.envelope, "--method",
                                  help="'envelope': crown envelope + radial distance map + space colonization "
                                       "(Argudo et al. 2016); 'learned': networks + bi-modal growth (Li et al. 2021); "
                                       "'abs': analysis by synthesis, foliage skeleton + L-system, best of N "
                                       "(Guénard et al. 2013)."),
    mask: Optional[Path] = typer.Option(None, "--mask", help="Tree mask image, white = tree (skips segmentation)."),
    out: Path = typer.Option(Path("out"), "--out", "-o", help="Output directory."),
    seed: int = seed_option(),
    species: Optional[str] = typer.Option(None, "--species",
                                          help="learned, abs: grow this species instead of the predicted one."),
    candidates: Optional[int] = typer.Option(None, "--candidates", min=1, max=10000,
                                             help="abs: models generated and scored by reprojection (default 24)."),
    crown: Crown = typer.Option(Crown.auto, "--crown", help="envelope: crown envelope shape (auto: conical for a "
                                                             "conifer --form, else round)."),
    form: Form = typer.Option(Form.auto, "--form", help="envelope: growth form: broadleaf (trunk splits into limbs "
                                                       "where the crown begins), conifer (one leader to the top, "
                                                       "laterals at 80 degrees, needles) or auto (from the "
                                                       "silhouette)."),
    leaves: Optional[int] = typer.Option(None, "--leaves",
                                         help="Number of leaf clusters (envelope default 8000; learned: per twig; "
                                              "abs: a cap on what the L-system grows)."),
    lod: Lod = typer.Option(Lod.medium, "--lod", help="Level of detail (triangle budget)."),
    height: Optional[float] = typer.Option(None, "--height",
                                           help="Tree height in metres (envelope and abs default 10; learned: the "
                                                "species')."),
    segmenter: Optional[SegmenterName] = typer.Option(
        None, "--segmenter", help=f"Tree segmentation: 'classical' (colour rules + graph cut) or 'learned' (network); "
                                  f"default {DEFAULT_SEGMENTER}."),
    foliage: FoliageKind = typer.Option(FoliageKind.auto, "--foliage",
                                        help="Leaf cards: broadleaf, needles (pine) or scales (thuja); auto: "
                                             "envelope needles for a conifer --form or --crown conical, learned "
                                             "the species'."),
    texture_size: Optional[int] = typer.Option(None, "--texture-size", min=16, max=8192, help=TEXTURE_SIZE_HELP),
    leaf_texture: Optional[LeafTexture] = typer.Option(
        None, "--leaf-texture", help="envelope, abs, learned: leaf cards wear the photo's own crown ('photo', "
                                     "default) or a drawn cluster (abs: leaf; learned: the species' leaves, "
                                     "envelope and abs tinted with the photo's colours) ('procedural')."),
    profile: Optional[Profile] = typer.Option(
        None, "--profile", help="envelope: crown side 'rounded' (default) or 'thin-plate' (paper's depth, deepest "
                                "where the front is widest)."),
    k: Optional[float] = typer.Option(None, "--k", min=0.01,
                                      help="envelope: silhouette tangent length k of the paper (default: the k that "
                                           "makes the crown as deep as --depth-ratio says)."),
    depth_ratio: Optional[float] = typer.Option(None, "--depth-ratio", min=0.05, max=5.0,
                                                help="envelope: crown depth / width (default 1)."),
    rdm_rotations: Optional[str] = typer.Option(
        None, "--rdm-rotations", metavar="DEG,DEG", help="envelope: extra copies of the envelope turned about the "
                                                         "vertical axis, e.g. 60,120 (the RDM keeps the largest radius)."),
    clumps: Optional[float] = typer.Option(
        None, "--clumps", min=0.0, max=10.0,
        help="envelope: spacing of the crown's foliage clumps as a fraction of its mean radius (default 0.4): "
             "leaves and the branches that carry them gather there, so the side and top show lobes, gaps and "
             "limbs; 0 spreads the leaves evenly (a solid crown from the side)."),
    colonization: Optional[Colonization] = typer.Option(
        None, "--colonization", help="envelope: space colonization 'coarse' (default: D = 0.04 r, branches "
                                     "leaving at about 45 degrees) or 'paper' (full detail: d_k = 0.01 r, D = 0.5 d_k, "
                                     "Runions's rule; slower, many more nodes)."),
    report: bool = typer.Option(False, "--report", help="Also write report.html: pictures, metrics, stage times, "
                                "the tree in a 3D viewer (opens offline)."),
    impostor: bool = typer.Option(False, "--impostor", help=IMPOSTOR_HELP),
    all_trees: bool = typer.Option(False, "--all-trees", help="Every tree of the photo: each found, reconstructed "
                                   "from its own crop into OUT/tree_K/, and placed on a common ground plane from "
                                   "where its trunk meets the ground (OUT/scene.glb, scene.json, preview.png)."),
    camera_height: Optional[float] = typer.Option(None, "--camera-height", min=0.1, max=500.0,
                                                  help="--all-trees: metres from the ground to the camera (default "
                                                       "1.6; the scene's scale, unless --height gives the tallest "
                                                       "tree's)."),
    feet: Optional[FeetSource] = typer.Option(None, "--feet", help="--all-trees: where each tree's trunk foot comes "
                                              "from: 'rules' (the mask's lowest points where wood rises), "
                                              "'learned' (the foot detector feet.onnx; the rules where it finds none) "
                                              "or 'both' (default)."),
):
    """Single photo -> 3D tree (tree.glb, tree.obj, skeleton, preview.png, metrics.json)."""
    from treeform.cli.progress import print_summary

    if camera_height is not None and not all_trees:
        typer.echo("error: --camera-height works with --all-trees", err=True)
        raise typer.Exit(2)
    if feet is not None and not all_trees:
        typer.echo("error: --feet works with --all-trees", err=True)
        raise typer.Exit(2)
    if all_trees and (mask is not None or report or impostor):
        bad = [n for n, v in (("--mask", mask), ("--report", report), ("--impostor", impostor)) if v]
        typer.echo(f"error: {', '.join(bad)}: not with --all-trees (each tree's mask comes from the photo)", err=True)
        raise typer.Exit(2)

    envelope_only = {"--leaf-texture": leaf_texture, "--profile": profile, "--k": k, "--depth-ratio": depth_ratio,
                     "--rdm-rotations": rdm_rotations, "--colonization": colonization, "--clumps": clumps,
                     "--form": None if form is Form.auto else form}
    given = [name for name, v in envelope_only.items() if v is not None]
    if candidates is not None and method is not Method.abs:
        typer.echo("error: --candidates works with --method abs", err=True)
        raise typer.Exit(2)
    if method is Method.abs:
        not_abs = [g for g in given if g != "--leaf-texture"]
        not_abs += ["--foliage"] if foliage is not FoliageKind.auto else []
        if not_abs:
            typer.echo(f"error: {', '.join(not_abs)}: not an option of --method abs", err=True)
            raise typer.Exit(2)
        from treeform.methods.synthesis.pipeline import STAGES
        from treeform.methods.synthesis.pipeline import reconstruct as api

        kw = dict(species=species, leaves=leaves, lod=lod.value, candidates=24 if candidates is None else candidates,
                  tree_height=10.0 if height is None else height,
                  segmenter=(segmenter or SegmenterName(DEFAULT_SEGMENTER)).value, stages=STAGES,
                  texture_size=texture_size, leaf_texture=(leaf_texture or LeafTexture.photo).value)
    elif method is Method.learned:
        given = [g for g in given if g != "--leaf-texture"]
        if given:
            typer.echo(f"error: {', '.join(given)} work{'s' if len(given) == 1 else ''} with --method envelope",
                       err=True)
            raise typer.Exit(2)
        from treeform.methods.learned.pipeline import STAGES
        from treeform.methods.learned.pipeline import reconstruct as api

        kw = dict(species=species, leaves=leaves, lod=lod.value, tree_height=height,
                  segmenter=(segmenter or SegmenterName.learned).value, stages=STAGES, foliage=foliage.value,
                  texture_size=texture_size, leaf_texture=(leaf_texture or LeafTexture.photo).value)
    else:
        from treeform.methods.envelope.pipeline import reconstruct as api

        if species is not None:
            typer.echo("error: --species works with --method learned or abs", err=True)
            raise typer.Exit(2)
        from treeform.methods.envelope.config import COLONIZATION_PRESETS

        try:
            rotations = tuple(float(a) for a in rdm_rotations.split(",") if a.strip()) if rdm_rotations else ()
        except ValueError:
            typer.echo(f"error: --rdm-rotations: expected degrees like 60,120, got {rdm_rotations!r}", err=True)
            raise typer.Exit(2) from None
        extra = {"rdm_rotations": rotations, "tangent_k": k, **COLONIZATION_PRESETS[(colonization or
                                                                                     Colonization.coarse).value]}
        if depth_ratio is not None:
            extra["depth_ratio"] = depth_ratio
        if profile is not None:
            extra["profile"] = profile.value
        if clumps is not None:
            extra["clumps"] = clumps
        kw = dict(crown=crown.value, form=form.value, leaves=8000 if leaves is None else leaves, lod=lod.value,
                  tree_height=10.0 if height is None else height,
                  segmenter=(segmenter or SegmenterName(DEFAULT_SEGMENTER)).value, foliage=foliage.value,
                  texture_size=texture_size, leaf_texture=(leaf_texture or LeafTexture.photo).value, **extra)
    if all_trees:
        from treeform.cli.progress import print_scene_summary
        from treeform.methods.scene.pipeline import SCENE_STAGES, reconstruct_all

        kw.pop("stages", None)
        kw.pop("segmenter", None)  # the trees are found by the network; each crop's mask is its instance
        kw["tree_height"] = height  # None: the scale comes from --camera-height
        res = run_api(reconstruct_all, photo, out=out, seed=seed, method_api=api, method=method.value,
                      camera_height=1.6 if camera_height is None else camera_height, inputs=(photo,),
                      feet=feet.value if feet is not None else None,
                      stages=SCENE_STAGES, **kw)
        print_scene_summary(res)
        return
    res = run_api(api, photo, mask=mask, out=out, seed=seed, inputs=(photo, ("--mask", mask)), **kw)
    print_summary(res)
    if report:
        write_report(out, f"treeform reconstruct --method {method.value}: {Path(photo).name}",
                     getattr(res, "rbv", None))
    if impostor:
        write_impostor(out, seed)


def write_impostor(out: Path, seed: int) -> None:
    """``--impostor`` of the reconstruct commands: :func:`make_impostor` of the folder just written."""
    from treeform.methods.envelope.impostor import IMPOSTOR_STAGES, make_impostor

    imp = run_api(make_impostor, out, seed=seed, stages=IMPOSTOR_STAGES)
    typer.echo(f" impostor                    {Path(next(iter(imp.files.values()))).parent}")


def write_report(out: Path, title: str, rbv=None, preview: str | None = None) -> None:
    """report.html in ``out`` (``--report`` of reconstruct, grow and multiview), with the RBV's picture when given."""
    from treeform.report import write_run_report
    from treeform.report.rbv_plot import plot_rbv

    pictures = [("radial bounding volume: top and side", plot_rbv(rbv))] if rbv is not None else []
    extra = {} if preview is None else {"preview_caption": preview}
    page = run_api(write_run_report, out, title=title, pictures=pictures, stages=("report",), **extra)
    typer.echo(f"report: {page}")


@app.command()
def demo(out: Path = typer.Option(Path("out/demo"), "--out", "-o", help="Output directory.")):
    """Reconstruct the bundled sample photo (Celtis occidentalis, public domain) into OUT."""
    from importlib.resources import files

    from treeform.cli.progress import print_summary
    from treeform.methods.envelope.pipeline import reconstruct as api

    sample = Path(str(files("treeform") / "data" / "Celtis_occidentalis_1.jpg"))
    res = run_api(api, sample, out=out)
    print_summary(res)


@app.command("sample-data")
def sample_data(out: Path = typer.Option(Path("samples"), "--out", "-o", help="Output directory.")):
    """Write the bundled sample set: photo.jpg, autumn.jpg, library/ (14 RGBA trees) and group.jpg into OUT."""
    from treeform.data import SAMPLE_STAGES, write_sample_data

    files = run_api(write_sample_data, out, stages=SAMPLE_STAGES)
    lib = sum(1 for k in files if k.startswith("library/"))
    typer.echo(f"photo.jpg, autumn.jpg, {lib} library trees and group.jpg in {out}")


def _register_commands() -> None:
    """Import every ``treeform/cli/cmd_*.py``; each adds its verbs with ``@app.command()``."""
    import importlib
    import pkgutil

    import treeform.cli as pkg

    for m in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda m: m.name):
        if m.name.startswith("cmd_"):
            importlib.import_module(f"treeform.cli.{m.name}")


_register_commands()


def _usage_line(exc) -> str:
    """A command-line usage error (wrong type, unknown choice or option, missing value) as the
    project's one ``error:`` line, with where to read the command's help."""
    msg = " ".join(exc.format_message().split())
    ctx = getattr(exc, "ctx", None)
    return f"error: {msg} (see '{ctx.command_path} --help')" if ctx is not None else f"error: {msg}"


def main(args=None):
    """The ``treeform`` command: usage errors are one ``error:`` line (exit 2), like every other error."""
    usage_error = typer.BadParameter.__mro__[1]  # click's UsageError (typer may vendor click)
    click_error = usage_error.__mro__[1]  # ClickException
    command = typer.main.get_command(app)
    try:
        rc = command.main(args=args, prog_name="treeform", standalone_mode=False)
    except (KeyboardInterrupt, typer.Abort):  # Ctrl-C in the command, or in a prompt
        typer.echo("interrupted", err=True)
        sys.exit(130)
    except usage_error as exc:
        if type(exc).__name__ == "NoArgsIsHelpError":  # a bare command: its help, as click would
            typer.echo(exc.ctx.get_help() if exc.ctx is not None else exc.format_message())
        else:
            sys.stdout.flush()
            typer.echo(_usage_line(exc), err=True)
        sys.exit(exc.exit_code)
    except click_error as exc:
        typer.echo(f"error: {' '.join(exc.format_message().split())}", err=True)
        sys.exit(exc.exit_code)
    sys.exit(rc if isinstance(rc, int) else 0)


if __name__ == "__main__":
    main()
