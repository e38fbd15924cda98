from setuptools import find_packages, setup

package_name = 'feedback_node'

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
    description=("The thesis's synthetic trainer: scalar feedback and Figure 5.1 utterances "
                 "from the agent's position; off when a person trains."),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'feedback_node = feedback_node.node:main',
        ],
    },
)
