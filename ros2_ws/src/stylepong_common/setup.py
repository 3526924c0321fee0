from setuptools import find_packages, setup

PACKAGE = 'stylepong_common'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='StylePong developers',
    maintainer_email='dev@stylepong.org',
    description='What every StylePong node shares: typed, validated parameters, throttled warnings, the executor loop.',
    license='Apache-2.0',
    entry_points={'console_scripts': []},
)
