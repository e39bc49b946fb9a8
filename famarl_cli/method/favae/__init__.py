"""FAVAE, the ladder VAE whose latents become the macro-action space.

- :mod:`~famarl_cli.method.favae.model`: the network and its config, K replicates as one batched model (a single
  FAVAE: K = 1);
- :mod:`~famarl_cli.method.favae.loss`: reconstruction, the capacity-controlled KL term and the information per latent;
- :mod:`~famarl_cli.method.favae.training`: the C_last pre-run, the fit (progressive, if asked) and its scores;
- :mod:`~famarl_cli.method.favae.checkpoint`: checkpoints and calibration files.
"""

from dataclasses import dataclass
from enum import StrEnum

from famarl_cli.core.declare import option
from famarl_cli.core.errors import UsageError


class Head(StrEnum):
    """What each ladder's head reads of its convolution features (:class:`~famarl_cli.method.favae.model.FavaeConfig`).
    Defined here, apart from the torch code, so the CLI starts without torch."""

    FLATTEN = "flatten"
    POOL = "pool"


class Decoder(StrEnum):
    """How the latents reach the output (:class:`~famarl_cli.method.favae.model.FavaeConfig`): ``ladder``, each ladder's
    latent joins the transposed convolutions at its own depth; ``shared``, all of them pass one MLP stack and then
    the same transposed convolutions (the layout before checkpoints recorded a decoder)."""

    LADDER = "ladder"
    SHARED = "shared"


class Join(StrEnum):
    """How a shallower ladder's latent joins the ladder decoder's path at its depth
    (:class:`~famarl_cli.method.favae.model.FavaeConfig`): ``linear``, one linear map to the feature map (added),
    or ``mlp``, a hidden layer first (VLAE's and pro-VLAE's nonlinear blocks), so that a shallow latent can make
    changes that are not linear in it."""

    LINEAR = "linear"
    MLP = "mlp"


class Capacity(StrEnum):
    """How the pre-run's C_last becomes the fit's capacities
    (:func:`~famarl_cli.method.favae.training.allocate_capacity`)."""

    MEASURED = "measured"
    DEEPEST = "deepest"
    HALF = "half"


class Measure(StrEnum):
    """What the capacity term |X_l - C_l| constrains (:func:`~famarl_cli.method.favae.loss.favae_loss`): ``kl``, the
    posterior's KL from the prior (the paper's; a constant shift of the posterior meets it and carries nothing), or
    ``information``, the part of that KL that varies with the input (a bound on the mutual information between
    segments and latents), the rest being penalised on its own."""

    INFORMATION = "information"
    KL = "kl"


class Device(StrEnum):
    """Where a FAVAE's pre-run and fit run (:func:`~famarl_cli.method.favae.training.fit_device`): the CPU, or torch's
    current CUDA GPU where there is one (nothing in famarl needs one)."""

    CPU = "cpu"
    CUDA = "cuda"


class Preset(StrEnum):
    """A FAVAE procedure by name (``famarl favae calibrate`` / ``fit`` / ``macros --preset``): ``famarl``, this
    project's (capacities on the information each ladder carries, ladders added deepest first over a fifth of the
    epochs, in the pre-run too, a pre-run of 0.3 of the fit's epochs), or ``paper``, the FaMARL paper's (capacities
    on the KL, every ladder from the start, the pre-run as long as the fit and its C_last a KL); docs/favae.md."""

    FAMARL = "famarl"
    PAPER = "paper"


# The design's defaults, torch-free so that the CLI's options, the model's config and the training's parameters
# read the same values (docs/favae.md has the measurements that chose them).
DECODER = Decoder.LADDER
MEASURE = Measure.INFORMATION
PROGRESSIVE = 0.2
"""Share of the epochs over which ladders are added one by one, deepest first (0: all from the start). 0.2 gives
the deepest ladder a tenth of the epochs alone: enough for it to take the whole-sequence factor (the direction of
down-and-up and pushed-down-only macros, most of 2D Reaching), and not so much that it takes the detail too."""
PRE_RUN = 0.3
"""The C_last pre-run's length in this project's procedure, a share of the fit's epochs. The pre-run follows the
fit's schedule (its ladders enter at the epochs they enter in the fit) and stops after this share; each ladder's
C_last is its mean over the pre-run's last third, or over the epochs since the last ladder came fully in where that
is shorter (:func:`~famarl_cli.method.favae.schedule.pre_run_window`). The pre-run as long as the fit was half of
every fit's arithmetic; the measurements that chose this share are in docs/favae.md ("The pre-run")."""
PRESETS = {Preset.FAMARL: (MEASURE, PROGRESSIVE, PRE_RUN), Preset.PAPER: (Measure.KL, 0.0, 1.0)}
"""Each preset's capacity measure, progressive share and pre-run share (the paper's pre-run is as long as its fit;
it reads C_last at the last epoch, ours as the mean of the pre-run's last third, a steadier reading of the same
settled value)."""
MAX_PROGRESSIVE = 0.8
"""The largest share: with two ladders the second then finishes fading in at the last epoch."""
CALIBRATION_BETA = 0.1
"""The paper's beta for the pre-run that measures C_last (with C = 0)."""
MAX_LADDERS = 8
"""The most ladders a FAVAE may have: each halves the sequence length, so 8 already needs 256-step segments."""


@dataclass(frozen=True)
class FavaeOptions:
    """What a FAVAE is made from and trained with, declared once for ``famarl favae calibrate``, ``favae fit`` and
    ``macros`` (:mod:`famarl_cli.core.declare`)."""

    ladders: int = option(3, "Number of ladders (latent groups, shallow to deep).", min=1, max=MAX_LADDERS)
    latent_dim: int = option(2, "Latent variables per ladder.", min=1)
    epochs: int = option(1500, "Training epochs (of the pre-run and of the fit).", min=1)
    seed: int = option(0, "Seed of the initialisation, batches and sampling.")
    head: Head = option(
        Head.FLATTEN,
        "What each ladder's head reads: flatten (its whole feature map) or pool (the map's mean over time).",
    )
    decoder: Decoder = option(
        DECODER,
        "How the latents reach the output: ladder (each ladder's latent joins the transposed convolutions at its own "
        "depth, so the deepest shapes the whole sequence) or shared (all through one MLP stack and the same "
        "convolutions, the design before the ladder decoder); docs/favae.md.",
    )
    join: Join = option(
        Join.LINEAR,
        "How a shallower ladder's latent joins the ladder decoder: linear (one linear map onto its feature map) or "
        "mlp (a hidden layer first); docs/favae.md.",
    )
    preset: Preset = option(
        Preset.FAMARL,
        "The FAVAE procedure: famarl (capacities on information, progressive ladders 0.2) or paper (the FaMARL "
        "paper's: capacities on KL, all ladders from the start, a pre-run as long as the fit); --capacity-measure, "
        "--progressive and --pre-run override it.",
    )
    capacity_measure: Measure | None = option(
        None,
        "What each ladder's capacity C constrains: information (what it carries about the segments, at most log N; "
        "the rest of its KL, a shift or narrowing shared by all, is penalised on its own) or kl (the paper's: the "
        "whole KL, which a constant shift of the posterior can meet while carrying nothing). Default: the preset's.",
    )
    progressive: float | None = option(
        None,
        "Share of the epochs over which the ladders are added one at a time, deepest first, each faded in "
        "(pro-VLAE); 0 trains all from the start. Default: the preset's (famarl 0.2, paper 0).",
        min=0.0,
        max=MAX_PROGRESSIVE,
    )
    calibration_beta: float = option(
        CALIBRATION_BETA, "The C_last pre-run's beta (the paper's 0.1), where the pre-run runs.", min=0.0, max=1e4
    )
    pre_run: float | None = option(
        None,
        "Length of the C_last pre-run, a share of --epochs: it follows the fit's schedule and stops there (at the "
        "earliest once every ladder is in); each ladder's C_last is its mean over the pre-run's last third "
        "(docs/favae.md). Default: the preset's (famarl 0.3, paper 1: as long as the fit).",
        min=0.01,
        max=1.0,
    )
    device: Device = option(
        Device.CPU,
        "Where the pre-run and the fit run: cpu, or cuda (torch's GPU, where there is one; its floats differ from "
        "the CPU's, so its fits do too, as two CPUs' do).",
    )

    def __post_init__(self) -> None:
        if self.join != Join.LINEAR and self.decoder != Decoder.LADDER:
            raise UsageError(f"--join {self.join} goes with --decoder ladder: the {self.decoder} decoder has no joins")

    def pre_run_window(self) -> range:
        """The epochs of the C_last pre-run whose mean is C_last (its last is the pre-run's last)."""
        from famarl_cli.method.favae.schedule import pre_run_window

        return pre_run_window(self.pre_run_share, self.epochs, self.ladders, self.progressive_share)

    @property
    def measure(self) -> Measure:
        """What the capacities constrain: the option, else the preset's."""
        return self.capacity_measure or PRESETS[self.preset][0]

    @property
    def progressive_share(self) -> float:
        """The progressive share: the option, else the preset's."""
        return PRESETS[self.preset][1] if self.progressive is None else self.progressive

    @property
    def pre_run_share(self) -> float:
        """The pre-run's share of the epochs: the option, else the preset's."""
        return PRESETS[self.preset][2] if self.pre_run is None else self.pre_run


@dataclass(frozen=True)
class FitChoices:
    """What the fit adds to the pre-run's options: its beta and how C_last becomes its capacities."""

    beta: float = option(50.0, "Weight of the capacity term (paper: 50 on ContinuousWorld).", min=0.0)
    capacity: Capacity = option(
        Capacity.MEASURED,
        "The fit's capacity per ladder: measured (the pre-run's C_last), deepest (their sum, all in the deepest "
        "ladder) or half (half of each shallower ladder's moved to the deepest); docs/favae.md.",
    )
