from setuptools import find_packages, setup

package_name = 'tamer_node'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    package_data={package_name: ['weights/*.pt']},
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Language-attention TAMER maintainers',
    maintainer_email='maintainers@example.org',
    description=('Deep TAMER learner with the saliency L2 loss; acts greedily and trains '
                 'asynchronously.'),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'tamer_node = tamer_node.node:main',
            'tamer_pretrain = tamer_node.pretrain:main',
        ],
    },
)
