from setuptools import find_packages, setup

PACKAGE = 'stylepong_viz'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml', 'README.md']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='StylePong developers',
    maintainer_email='dev@stylepong.org',
    description='The cell, the teaching and the player in a browser: rerun web viewer, live or from a bag.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'viewer = stylepong_viz.viewer_node:main',
        ],
    },
)
