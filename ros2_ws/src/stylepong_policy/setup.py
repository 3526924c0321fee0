from glob import glob
from os.path import isfile

from setuptools import find_packages, setup

PACKAGE = 'stylepong_policy'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
        ('share/' + PACKAGE + '/models', [f for f in glob('models/*') if isfile(f)]),
        ('share/' + PACKAGE + '/models/skills', glob('models/skills/*.pt')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='StylePong developers',
    maintainer_email='dev@stylepong.org',
    description='Training bridge (bags to reference motions), PPO + AMP training, evaluation and the paper figures.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            # The names are what users type (`ros2 run stylepong_policy <name>`); the modules behind them
            # are grouped by role, so a name never follows a module when it moves.
            'build_dataset = stylepong_policy.training.build_dataset:main',
            'train = stylepong_policy.training.train:main',
            'select_checkpoint = stylepong_policy.training.select_checkpoint:main',
            'average_checkpoints = stylepong_policy.training.average_checkpoints:main',
            'learn_style = stylepong_policy.training.learn_style:main',
            'evaluate = stylepong_policy.evaluation.evaluate:main',
            'demo_returns = stylepong_policy.evaluation.demo_returns:main',
            'offline_rallies = stylepong_policy.evaluation.offline_rallies:main',
            'replay_clip = stylepong_policy.evaluation.player_replay:main',
            'paper_tables = stylepong_policy.reports.paper_tables:main',
            'style_confusion = stylepong_policy.reports.style_confusion:main',
            'style_generalisation = stylepong_policy.reports.style_generalisation:main',
            'compare_demo_sets = stylepong_policy.reports.compare_demo_sets:main',
            'ship_run = stylepong_policy.shipping.ship_run:main',
            'ship_skill = stylepong_policy.shipping.ship_skill:main',
            'amp_sequence_length = stylepong_policy.experiments.amp_sequence_length:main',
            'amp_frame_features = stylepong_policy.experiments.amp_frame_features:main',
            # The user's pipeline ends in this package (learn_style, then play the actor), so the
            # player is offered under its name too; the one implementation stays in
            # stylepong_player, which the robot computer installs without torch.
            'player = stylepong_player.player_node:main',
        ],
    },
)
