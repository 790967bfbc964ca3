"""The plugin registry: every controller, metric and figure comes from an installed plugin.

A plugin is an installed package that declares, in its ``pyproject.toml``::

    [project.entry-points."walkrepro.plugins"]
    my_lab = "my_lab.walkrepro_plugin:PLUGIN"

where ``PLUGIN`` is a :class:`Plugin`. walkrepro's own controllers and papers are plugins
declared the same way in walkrepro's ``pyproject.toml`` (``walkrepro/papers/``); nothing
about them is special. A guide with a worked outside package: ``docs/plugins.md`` and
``examples/walkrepro-example-plugin/``.

Declarations are strings, so that nothing is imported before it is needed:

- the controller names are known from the declarations; a controller's module is imported
  when a spec names it;
- the metric modules are imported on the first metric lookup (a spec's validation needs
  every metric name), and register their metrics with :func:`walkrepro.evaluation.metrics.metric`;
- a paper's figure module is imported when a run of that paper draws its figures;
- a controller's plot declarations are imported when a viewer export draws them
  (``walkrepro export --rerun``).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import import_module, metadata

from walkrepro.errors import WalkreproError

#: The entry-point group plugins register under.
GROUP = "walkrepro.plugins"
#: The distribution whose plugins are walkrepro's own (listed first; their documentation is
#: generated here, an outside plugin documents its own).
DISTRIBUTION = "walkrepro"


@dataclass(frozen=True)
class Paper:
    """A paper a plugin reproduces: the key its specs name and how walkrepro names it.

    Attributes:
        key: a spec's ``paper.key``; also the name of the paper's deviations page
            (``docs/deviations/<key>.md``) and calibration file
            (``experiments/calibration/<key>.yaml``).
        citation: the paper as the spec reference and the report cite it, e.g. ``Lee et al.,
            Toward Reactive Walking (E-FSM + OS-WBC)``.
        label: the paper as the README's status table and the generated documents head it,
            e.g. ``Paper I — Lee et al., Toward Reactive Walking (E-FSM, `dyros_red`)``.
        title: the paper as a figure's title names it, e.g. ``Lee et al. 2021``.
        order: where lists of papers put it, ascending (then by key): walkrepro's papers
            are 1-3 and its sanity experiments last; an outside paper's default puts it
            after walkrepro's papers, before the sanity experiments.
        headline: the experiment and the figure (its file's stem under the experiment's
            ``figures/``) the report's index shows for the paper, with a frame of the
            robot from that experiment's ``snapshots.png``; None: no picture.
    """

    key: str
    citation: str
    label: str
    title: str
    order: int = 100
    headline: tuple[str, str] | None = None


@dataclass(frozen=True)
class Plugin:
    """What a plugin adds, as import paths, and the papers it reproduces.

    Attributes:
        controllers: ``controller.type`` name -> ``"module:Class"``, a subclass of
            :class:`walkrepro.controllers.Controller`.
        metric_modules: modules whose import registers metrics with
            :func:`walkrepro.evaluation.metrics.metric`.
        figures: paper key (a spec's ``paper.key``) -> a module holding ``FIGURES`` (functions
            ``(LogData, out_dir) -> [paths]``) and optionally ``COMPARE`` (functions
            ``(LogData, LogData, out_dir) -> [paths]``).
        plots: ``controller.type`` name -> ``"module:ATTR"``, a tuple of
            :class:`walkrepro.present.plots.Plot`: the controller's key signals with their units,
            which viewers of a run draw (``walkrepro export --rerun``).
        papers: the papers this plugin reproduces (:class:`Paper`): a spec's ``paper.key``
            must name one.
    """

    controllers: Mapping[str, str] = field(default_factory=dict)
    metric_modules: tuple[str, ...] = ()
    figures: Mapping[str, str] = field(default_factory=dict)
    plots: Mapping[str, str] = field(default_factory=dict)
    papers: tuple[Paper, ...] = ()


@dataclass(frozen=True)
class Registered:
    """A loaded plugin: its entry-point name and target, the distribution that installed
    it, and it."""

    name: str
    distribution: str
    plugin: Plugin
    target: str = ""

    @property
    def own(self) -> bool:
        """One of walkrepro's own plugins (installed by walkrepro's distribution)."""
        return self.distribution == DISTRIBUTION


def _own_modules() -> set[str]:
    """The modules of walkrepro's own plugins, from the package's files (not the install's
    metadata): the core's, and each paper folder's under ``walkrepro/papers/``."""
    import pkgutil
    from pathlib import Path

    papers = Path(__file__).resolve().parent / "papers"
    folders = {m.name for m in pkgutil.iter_modules([str(papers)]) if m.ispkg}
    return {__name__} | {f"walkrepro.papers.{name}" for name in folders}


@functools.cache
def registered() -> tuple[Registered, ...]:
    """Every installed plugin, walkrepro's own first, then by name.

    Raises:
        WalkreproError: an entry point that does not load or is not a :class:`Plugin`, or
            walkrepro's own plugins are missing (install metadata older than this code).
    """
    found = []
    for ep in metadata.entry_points(group=GROUP):
        where = f"plugin {ep.name!r} ({ep.value}"
        dist = ep.dist.name if ep.dist is not None else "unknown distribution"
        try:
            plugin = ep.load()
        except Exception as exc:  # noqa: BLE001 - any import error of a third-party plugin
            raise WalkreproError(
                f"{where}, from {dist}) does not load: {type(exc).__name__}: {exc}"
            ) from None
        if not isinstance(plugin, Plugin):
            raise WalkreproError(
                f"{where}, from {dist}) is a {type(plugin).__name__}, not a "
                "walkrepro.plugins.Plugin."
            )
        found.append(Registered(ep.name, dist, plugin, ep.value))
    declared = {r.target.partition(":")[0] for r in found}
    missing = sorted(_own_modules() - declared)
    if missing:
        raise WalkreproError(
            f"walkrepro's own plugins ({', '.join(missing)}) are not registered: the install's "
            "metadata is older than this code. Reinstall: pip install -e . (from the clone)."
        )
    return tuple(sorted(found, key=lambda r: (not r.own, r.name)))


def _merged(kind: str, label: str) -> dict[str, str]:
    """``name -> target`` of one kind (a :class:`Plugin` field) across plugins; a name that
    two plugins declare differently is an error naming both."""
    merged: dict[str, str] = {}
    owner: dict[str, str] = {}
    for reg in registered():
        for name, target in getattr(reg.plugin, kind).items():
            if name in merged and merged[name] != target:
                raise WalkreproError(
                    f"{label} {name!r} is declared by two plugins: {owner[name]} "
                    f"({merged[name]}) and {reg.name} from {reg.distribution} ({target}); "
                    "uninstall one."
                )
            merged[name], owner[name] = target, f"{reg.name} from {reg.distribution}"
    return merged


@functools.cache
def papers() -> dict[str, Paper]:
    """Every declared paper by key, in their :attr:`Paper.order` (then by key).

    Raises:
        WalkreproError: two plugins declare one key.
    """
    found: dict[str, Paper] = {}
    owner: dict[str, str] = {}
    for reg in registered():
        for paper in reg.plugin.papers:
            if paper.key in found and found[paper.key] != paper:
                raise WalkreproError(
                    f"paper {paper.key!r} is declared by two plugins: {owner[paper.key]} and "
                    f"{reg.name} from {reg.distribution}; uninstall one."
                )
            found[paper.key], owner[paper.key] = paper, f"{reg.name} from {reg.distribution}"
    return {p.key: p for p in sorted(found.values(), key=lambda p: (p.order, p.key))}


@functools.cache
def controllers() -> dict[str, str]:
    """Every controller type name -> ``"module:Class"``."""
    return _merged("controllers", "controller")


@functools.cache
def figure_modules() -> dict[str, str]:
    """Every paper key with figures -> its figure module."""
    return _merged("figures", "the figures of paper")


@functools.cache
def plot_declarations() -> dict[str, str]:
    """Every controller type with declared plots -> ``"module:ATTR"``."""
    return _merged("plots", "the plots of controller")


def load(target: str) -> object:
    """Import ``"module:attr"`` (or a module) and return the object."""
    module, _, attr = target.partition(":")
    loaded = import_module(module)
    return getattr(loaded, attr) if attr else loaded


@functools.cache
def load_metric_modules() -> None:
    """Import every plugin's metric modules once (they register their metrics on import)."""
    for reg in registered():
        for module in reg.plugin.metric_modules:
            import_module(module)


#: walkrepro's core plugin: its sanity experiments (``paper.key: walkrepro``) and their posture
#: controller. The core metrics register in :mod:`walkrepro.evaluation.metrics` itself, the overview
#: figure is every run's.
CORE = Plugin(
    papers=(
        Paper(
            key="walkrepro",
            citation="walkrepro sanity experiment (no paper figure)",
            label="walkrepro's own sanity checks (standing still)",
            title="walkrepro",
            order=1000,
        ),
    ),
    controllers={"posture": "walkrepro.controllers.posture:PostureController"},
)
