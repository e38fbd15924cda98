from setuptools import find_packages, setup

package_name = 'env_node'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Language-attention TAMER maintainers',
    maintainer_email='maintainers@example.org',
    description=("Atari Montezuma's Revenge (ALE) as a ROS 2 node: observations, agent position "
                 'and /clock out, Joy actions in.'),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'env_node = env_node.node:main',
        ],
    },
)
