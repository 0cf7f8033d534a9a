# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
security/policy.xml: a valid SROS2 policy that lets only /supervisor command the bridge.

The document is checked structurally against the rules of sros2's policy schema
(sros2/policy/schemas/policy.xsd, policy version 0.2.0: elements, their order and counts,
required attributes, ALLOW/DENY qualifiers), written out here so the test needs neither
sros2 nor the network. Then the permissions are evaluated as SROS2 generates them (DENY
before ALLOW, everything else denied) for every service and topic a real bridge node with
every device type creates.
"""
from __future__ import annotations

import fnmatch
import importlib.util
from pathlib import Path
import xml.etree.ElementTree as ET

import pytest

from helpers import every_device_bridge

POLICY = Path(__file__).resolve().parents[1] / 'security' / 'policy.xml'
GENERATOR = Path(__file__).resolve().parents[1] / 'scripts' / 'policy_xml.py'
XML_BASE = '{http://www.w3.org/XML/1998/namespace}base'
QUALIFIERS = ('ALLOW', 'DENY')
# element: (allowed attributes, required attributes, {child: (min, max)}, ordered children)
SCHEMA = {
    'policy': ({'version'}, {'version'}, {'contexts': (1, 1)}),
    'contexts': (set(), set(), {'context': (1, None)}),
    'context': ({'path'}, {'path'}, {'profiles': (1, None)}),
    'profiles': ({'type'}, set(), {'profile': (1, None), 'metadata': (0, 1)}),
    'profile': ({'ns', 'node', XML_BASE}, {'ns', 'node'},
                {'topics': (0, None), 'services': (0, None), 'actions': (0, None)}),
    'topics': ({'publish', 'subscribe', XML_BASE}, set(), {'topic': (1, None)}),
    'services': ({'reply', 'request', XML_BASE}, set(), {'service': (1, None)}),
    'actions': ({'call', 'execute', XML_BASE}, set(), {'action': (1, None)}),
}
EXPRESSIONS = {'topic', 'service', 'action'}


def schema_errors(element: ET.Element, path: str = '') -> list[str]:
    """List every way element (and its subtree) breaks the sros2 policy schema."""
    tag, where = element.tag, f'{path}/{element.tag}'
    if tag in EXPRESSIONS:
        errors = [f'{where}: {child.tag} inside an expression' for child in element]
        errors += [f'{where}: attribute {a}' for a in element.attrib]
        if not (element.text or '').strip():
            errors.append(f'{where}: empty expression')
        return errors
    if tag not in SCHEMA:
        return [f'{where}: unknown element']
    allowed, required, children = SCHEMA[tag]
    errors = [f'{where}: attribute {a} not allowed' for a in element.attrib if a not in allowed]
    errors += [f'{where}: attribute {a} missing' for a in required if a not in element.attrib]
    for attribute in ('publish', 'subscribe', 'reply', 'request', 'call', 'execute'):
        if attribute in element.attrib and element.attrib[attribute] not in QUALIFIERS:
            errors.append(f'{where}: {attribute}={element.attrib[attribute]!r}, not ALLOW/DENY')
    if (element.text or '').strip():
        errors.append(f'{where}: text where elements belong')
    tags = [child.tag for child in element]
    for child_tag, (low, high) in children.items():
        count = tags.count(child_tag)
        if count < low or (high is not None and count > high):
            errors.append(f'{where}: {count} <{child_tag}>, allowed {low}..{high or "n"}')
    if tag == 'profiles' and 'metadata' in tags and tags[-1] != 'metadata':
        errors.append(f'{where}: metadata must come after the profiles')
    for child in element:
        if child.tag == 'metadata':
            continue  # xs:anyType
        if child.tag not in children:
            errors.append(f'{where}: <{child.tag}> not allowed here')
        else:
            errors += schema_errors(child, where)
    return errors


class Profile:
    """One profile: its rules as (kind, qualifier name, ALLOW/DENY, fully qualified pattern)."""

    def __init__(self, enclave: str, element: ET.Element) -> None:
        self.enclave = enclave
        self.node = element.attrib['node']
        self.ns = element.attrib['ns'].rstrip('/')
        self.rules = []
        for group in element:
            for qualifier, verdict in group.attrib.items():
                for expression in group:
                    self.rules.append((group.tag, qualifier, verdict,
                                       self._resolve(expression.text.strip())))

    def _resolve(self, name: str) -> str:
        if name.startswith('~'):
            return f'{self.ns}/{self.node}/{name[1:].lstrip("/")}'
        return name if name.startswith('/') else f'{self.ns}/{name}'

    def allows(self, kind: str, qualifier: str, name: str) -> bool:
        """Evaluate as DDS permissions do: a matching DENY wins, default deny."""
        verdicts = {v for k, q, v, pattern in self.rules
                    if k == kind and q == qualifier and fnmatch.fnmatchcase(name, pattern)}
        return 'DENY' not in verdicts and 'ALLOW' in verdicts


def profiles(root: ET.Element) -> dict[str, Profile]:
    return {context.attrib['path']: Profile(context.attrib['path'], profile)
            for context in root.iter('context') for profile in context.iter('profile')}


@pytest.fixture(scope='module')
def bridge():
    with every_device_bridge('policy-test') as node:
        yield node


def generator():
    spec = importlib.util.spec_from_file_location('policy_xml', GENERATOR)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_checked_in_policy_is_the_generators_output_from_the_descriptors():
    gen = generator()
    assert POLICY.read_text() == gen.policy(), (
        'security/policy.xml is out of date with the device types: run '
        '.venv/bin/python scripts/policy_xml.py')
    # every command row of every device type (and variant) is in it, for the supervisor
    supervisor = profiles(ET.fromstring(gen.policy()))['/supervisor']
    from ams_can_bridge import registry
    rows = [(name, row.service) for name, found in registry.DESCRIPTORS.items()
            for variant in (found.variant_names or (None,)) for row in found.commands(variant)]
    assert len(rows) >= 25
    for name, service in rows:
        assert supervisor.allows('services', 'request', f'/{name}/{service}'), (name, service)


def test_policy_is_valid_against_the_sros2_schema():
    root = ET.parse(POLICY).getroot()
    assert root.tag == 'policy' and root.attrib['version'] == '0.2.0'
    assert schema_errors(root) == []


@pytest.mark.parametrize('broken', [
    ('<policy version="0.2.0"><contexts><context path="/x"><profiles><profile ns="/">'
     '<services request="ALLOW"><service>a</service></services></profile></profiles>'
     '</context></contexts></policy>', 'attribute node missing'),
    ('<policy version="0.2.0"><contexts><context path="/x"><profiles><profile ns="/" '
     'node="n"><services request="MAYBE"><service>a</service></services></profile>'
     '</profiles></context></contexts></policy>', "request='MAYBE'"),
    ('<policy><contexts/></policy>', 'attribute version missing'),
])
def test_the_schema_check_catches_broken_policies(broken):
    text, expected = broken
    assert any(expected in e for e in schema_errors(ET.fromstring(text)))


def test_only_the_supervisor_may_command_the_bridge_or_set_its_parameters(bridge):
    rules = profiles(ET.parse(POLICY).getroot())
    own = rules.pop('/ams_can_bridge')
    supervisor = rules['/supervisor']
    assert own.node == bridge.get_name() and f'{own.ns}/' == bridge.get_namespace().rstrip(
        '/') + '/'
    services = [name for name, _ in bridge.get_service_names_and_types_by_node(
        bridge.get_name(), bridge.get_namespace())]
    commands = [s for s in services if s.split('/')[1] in bridge.devices]
    setters = [s for s in services if s.endswith(('/set_parameters',
                                                 '/set_parameters_atomically'))]
    assert len(commands) >= 18 and len(setters) == 2, services
    for service in services:
        assert own.allows('services', 'reply', service), f'the bridge may not serve {service}'
    lifecycle = [s for s in services if s.endswith('/change_state')]  # deactivate = disarm
    assert len(lifecycle) == 1, services
    for service in commands + setters + lifecycle:
        assert supervisor.allows('services', 'request', service), service
        for path, profile in rules.items():
            if path != '/supervisor':
                assert not profile.allows('services', 'request', service), (path, service)
    # reading parameters stays open to the monitor
    assert rules['/monitor'].allows('services', 'request', '/ams_can_bridge/get_parameters')


def test_the_bridge_may_publish_everything_it_publishes(bridge):
    own = profiles(ET.parse(POLICY).getroot())['/ams_can_bridge']
    topics = [name for name, _ in bridge.get_publisher_names_and_types_by_node(
        bridge.get_name(), bridge.get_namespace())]
    assert '/diagnostics' in topics
    assert [t for t in topics if not own.allows('topics', 'publish', t)] == []
