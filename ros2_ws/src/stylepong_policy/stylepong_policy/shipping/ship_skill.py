"""Put a learn_style run's network into the skill library that learn_style starts new styles from.

    ros2 run stylepong_policy ship_skill --run runs/style_compact --name compact [--models-dir MODELS]

MODELS defaults to ros2_ws/src/stylepong_policy/models.

Writes <models>/skills/<name>.pt, the run's actor_checkpoint.pt with the demonstrations behind it
(stylepong_policy.training.skills.LINEAGE_KEY; a run from before learn_style recorded them gets them from its
dataset and the runs its starts came from), and <name>.json, its record: the lineage, the command, the skill
it started from, its train/choose/evaluate facts (learn_style.json), and every value of the run's config
that differs from config/amp.yaml. Needs the workspace built (make setup). Nothing is typed by hand.
"""

from __future__ import annotations

import json
import pathlib
import sys

import torch

from stylepong_policy.shipping import shipping_parser

# Values every learn_style run sets for itself: not a difference of recipe.
RUN_OWN_KEYS = ('amp.dataset', 'runner.progress_bar', 'runner.device')


def flat(tree: dict, prefix: str = '') -> dict:
    """A nested config as {'section.key': value}."""
    out = {}
    for key, value in tree.items():
        out.update(flat(value, f'{prefix}{key}.') if isinstance(value, dict) else {f'{prefix}{key}': value})
    return out


def recipe_differences(run_config: pathlib.Path, recipe: pathlib.Path) -> dict:
    """{key: [the run's value, the recipe's]} for every config value the run did not share with the recipe
    (both read as training reads them, defaults filled in)."""
    from stylepong_policy.rl.config import config_to_dict, load_config

    ran, written = (flat(config_to_dict(load_config(path))) for path in (run_config, recipe))
    return {
        key: [ran.get(key), written.get(key)]
        for key in sorted(set(ran) | set(written))
        if key not in RUN_OWN_KEYS and ran.get(key) != written.get(key)
    }


def run_lineage(run: pathlib.Path) -> list[str]:
    """The demonstrations behind a learn_style run's network: as it records them, else its own and, through
    the run directories its starts came from, its starts' (runs from before learn_style recorded them)."""
    from stylepong_policy.training import learn_style, skills

    paths = learn_style.paths_of(run)
    recorded = skills.lineage_of(torch.load(paths.actor_checkpoint, map_location='cpu', weights_only=False))
    if recorded:
        return list(recorded)
    start = pathlib.Path(learn_style.read_state(paths)['skill'])
    before = (
        run_lineage(start.parent)
        if (start.parent / learn_style.STATE_NAME).is_file()
        else list(skills.lineage_of(torch.load(start, map_location='cpu', weights_only=False)))
    )
    return skills.lineage_after({skills.LINEAGE_KEY: before}, learn_style.fingerprint_of(paths))


def ship_skill(run: pathlib.Path, name: str, models: pathlib.Path) -> list[pathlib.Path]:
    """Copy the run's network and its record into models/skills; returns the files written."""
    from stylepong_policy.evaluation.evaluate import portable_path
    from stylepong_policy.training import learn_style, skills
    from stylepong_policy.training.train import default_config_path

    paths = learn_style.paths_of(run)
    state = learn_style.read_state(paths)
    if 'export' not in state.get('stages', {}):
        raise FileNotFoundError(f'{run}: no exported learn_style run (its export stage has not finished)')
    checkpoint = torch.load(paths.actor_checkpoint, map_location='cpu', weights_only=False)
    checkpoint[skills.LINEAGE_KEY] = run_lineage(run)
    library = models / skills.LIBRARY_DIR
    library.mkdir(parents=True, exist_ok=True)
    network = library / f'{name}.pt'
    torch.save(checkpoint, network)
    stages = state['stages']
    record = {
        'name': name,
        skills.LINEAGE_KEY: list(skills.lineage_of(checkpoint)),
        'demonstrations': portable_path(state['source']),
        'command': state['command'],
        'started_from': portable_path(state['skill']),
        **{stage: stages[stage] for stage in ('skill', 'train', 'choose', 'evaluate') if stage in stages},
        'recipe_differences': recipe_differences(paths.train / 'config.yaml', default_config_path('amp')),
    }
    path = library / f'{name}.json'
    path.write_text(json.dumps(record, indent=2) + '\n')
    return [network, path]


def main(argv: list[str] | None = None) -> int:
    """Entry point: ship the run's network; exit code 2 with one line when the run is not a finished one."""
    run_help, name_help = 'a finished learn_style run directory', "the skill's name in the library (a file stem)"
    parser = shipping_parser('ship_skill', __doc__.split('\n\n')[0], run_help, name_help)
    args = parser.parse_args(argv)
    try:
        for path in ship_skill(args.run, args.name, args.models_dir):
            print(f'wrote {path}')
    except (FileNotFoundError, KeyError) as err:
        print(f'ship_skill: {err}', file=sys.stderr)
        return 2
    return 0


if __name__ == '__main__':
    sys.exit(main())
