"""Per-decision against semi-MDP discounting when decisions differ in length (docs/rl.md, "The hybrid agent").

Walks a 100-step constant-penalty path (famarl_cli.rl.semi_mdp.ConstantPenaltyEnv) in macro actions of one length
through the training code's executor and reward function, and prints the discounted return from the start that
PPO's targets would count, per unit of penalty, with and without a terminal bonus.

    python studies/length_neutrality.py
"""

from famarl_cli.rl.semi_mdp import path_value

LENGTHS = (1, 10, 25, 100)

if __name__ == "__main__":
    print(
        "| reward per step, path of 100 steps, gamma 0.99 | discount | "
        + " | ".join(f"L = {n}" for n in LENGTHS)
        + " |"
    )
    print("|---|---|" + "---|" * len(LENGTHS))
    for bonus in (0.0, 100.0):
        for discount in ("decision", "steps"):
            values = " | ".join(f"{path_value(n, discount, bonus=bonus):.1f}" for n in LENGTHS)
            what = "-1" + (f", +{bonus:g} at the end" if bonus else "")
            print(f"| {what} | {discount} | {values} |")
