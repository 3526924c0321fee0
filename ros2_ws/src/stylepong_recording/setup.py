from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'stylepong_recording'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='StylePong developers',
    maintainer_email='dev@stylepong.org',
    description='Labelled demonstration clips from any joint-state source: the recorder node, crash-safe rosbag2 '
    'writing, bag recovery and the bag layout readers share.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'recorder = stylepong_recording.recorder_node:main',
            'recover_bag = stylepong_recording.recover_bag:main',
            'compress_bag = stylepong_recording.compress_bag:main',
        ],
    },
)
