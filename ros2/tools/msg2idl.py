#!/usr/bin/python3
# SPDX-License-Identifier: BSD-3-Clause
"""ROS 2 .msg files -> DDS IDL in the ROS 2 conventions, REP 2011 type hashes, a C++ traits header.

Usage: msg2idl.py MSG_ROOT OUT_DIR HEADER pkg/Name [pkg/Name ...]

MSG_ROOT/<pkg>/<Name>.msg are parsed with Debian's rosidl_adapter parser (python3-rosidl). For
each message this writes
  OUT_DIR/<pkg>/msg/dds_/<Name>_.idl   module <pkg>::msg::dds_, @final struct <Name>_ (the type
                                       name rmw_cyclonedds_cpp and rmw_fastrtps_cpp register);
  OUT_DIR/<pkg>/msg/<Name>.json        the canonical type description the hash is taken of;
and HEADER, a C++ header with one Ros2Type<> specialisation per message (ROS name, DDS type
name, RIHS01 hash, the idlc topic descriptor). Errors name the .msg file and the field.

The hash follows REP 2011 (RIHS01): SHA-256 of the JSON of {type_description,
referenced_type_descriptions} (the referenced types sorted by name, each field as name and type
{type_id, capacity, string_capacity, nested_type_name}, no default values), serialised with
', ' and ': ' separators, no indentation, ASCII only.
"""
import hashlib
import json
import sys
from pathlib import Path

from rosidl_adapter.parser import parse_message_file

# FieldType ids of type_description_interfaces (REP 2011). A .msg `char` is an IDL uint8 and a
# .msg `byte` an IDL octet, as rosidl's .msg -> .idl conversion maps them.
BASE_TYPE_ID = {
    'int8': 2, 'uint8': 3, 'char': 3, 'int16': 4, 'uint16': 5, 'int32': 6, 'uint32': 7,
    'int64': 8, 'uint64': 9, 'float32': 10, 'float64': 11, 'bool': 15, 'byte': 16,
    'string': 17, 'wstring': 18,
}
NESTED_TYPE_ID = 1
BOUNDED_STRING_ID = {'string': 21, 'wstring': 22}
ARRAY_OFFSET = 48
UNBOUNDED_SEQUENCE_OFFSET = 144

IDL_BASE_TYPE = {
    'int8': 'int8', 'uint8': 'uint8', 'char': 'uint8', 'int16': 'int16', 'uint16': 'uint16',
    'int32': 'int32', 'uint32': 'uint32', 'int64': 'int64', 'uint64': 'uint64',
    'float32': 'float', 'float64': 'double', 'bool': 'boolean', 'byte': 'octet',
    'string': 'string', 'wstring': 'wstring',
}
CPP_CONSTANT_TYPE = {
    'int8': 'std::int8_t', 'uint8': 'std::uint8_t', 'char': 'std::uint8_t', 'byte': 'std::uint8_t',
    'int16': 'std::int16_t', 'uint16': 'std::uint16_t', 'int32': 'std::int32_t',
    'uint32': 'std::uint32_t', 'int64': 'std::int64_t', 'uint64': 'std::uint64_t',
    'float32': 'float', 'float64': 'double', 'bool': 'bool',
}


class MsgError(Exception):
    pass


def ros_name(pkg, name):
    return f'{pkg}/msg/{name}'


def field_type_description(msg_file, field):
    """The {type_id, capacity, string_capacity, nested_type_name} of one field."""
    t = field.type
    if t.is_array and t.is_upper_bound:
        raise MsgError(f'{msg_file}: field {field.name}: bounded sequences are not supported')
    if t.is_primitive_type():
        if t.string_upper_bound is not None:
            type_id, string_capacity = BOUNDED_STRING_ID[t.type], t.string_upper_bound
        else:
            type_id, string_capacity = BASE_TYPE_ID[t.type], 0
        nested = ''
    else:
        type_id, string_capacity, nested = NESTED_TYPE_ID, 0, ros_name(t.pkg_name, t.type)
    capacity = 0
    if t.is_array:
        if t.array_size is not None:
            type_id += ARRAY_OFFSET
            capacity = t.array_size
        else:
            type_id += UNBOUNDED_SEQUENCE_OFFSET
    return {'type_id': type_id, 'capacity': capacity, 'string_capacity': string_capacity,
            'nested_type_name': nested}


def individual_description(msg_file, spec):
    fields = [{'name': f.name, 'type': field_type_description(msg_file, f)} for f in spec.fields]
    if not fields:  # rosidl gives an empty message one member (IDL structs cannot be empty)
        fields = [{'name': 'structure_needs_at_least_one_member',
                   'type': {'type_id': BASE_TYPE_ID['uint8'], 'capacity': 0,
                            'string_capacity': 0, 'nested_type_name': ''}}]
    return {'type_name': ros_name(spec.base_type.pkg_name, spec.msg_name), 'fields': fields}


def full_description(type_name, individual):
    """The type and every type it references (transitively), sorted by name."""
    referenced = set()
    queue = [f['type']['nested_type_name'] for f in individual[type_name]['fields']]
    while queue:
        name = queue.pop()
        if not name or name in referenced:
            continue
        if name not in individual:
            raise MsgError(f'{type_name}: references {name}, which is not among the messages')
        referenced.add(name)
        queue.extend(f['type']['nested_type_name'] for f in individual[name]['fields'])
    return {'type_description': individual[type_name],
            'referenced_type_descriptions': [individual[n] for n in sorted(referenced)]}


def canonical_json(full):
    return json.dumps(full, skipkeys=False, ensure_ascii=True, check_circular=True,
                      allow_nan=False, indent=None, separators=(', ', ': '), sort_keys=False)


def type_hash(full):
    return 'RIHS01_' + hashlib.sha256(canonical_json(full).encode('utf-8')).hexdigest()


def idl_member(field):
    t = field.type
    if t.is_primitive_type():
        base = IDL_BASE_TYPE[t.type]
        if t.string_upper_bound is not None:
            base = f'{base}<{t.string_upper_bound}>'
    else:
        base = f'{t.pkg_name}::msg::dds_::{t.type}_'
    if t.is_array and t.array_size is not None:
        return f'{base} {field.name}[{t.array_size}];'
    if t.is_array:
        return f'sequence<{base}> {field.name};'
    return f'{base} {field.name};'


def idl_text(spec):
    pkg, name = spec.base_type.pkg_name, spec.msg_name
    includes = sorted({f'{f.type.pkg_name}/msg/dds_/{f.type.type}_.idl' for f in spec.fields
                       if not f.type.is_primitive_type()})
    guard = f'FNMPC_ROS2_{pkg}_{name}_IDL'.upper()
    lines = [f'// Generated by ros2/tools/msg2idl.py from {pkg}/{name}.msg: do not edit.',
             f'#ifndef {guard}', f'#define {guard}']
    lines += [f'#include "{inc}"' for inc in includes]
    lines += [f'module {pkg} {{ module msg {{ module dds_ {{']
    if spec.constants:
        lines.append(f'module {name}_Constants {{')
        for c in spec.constants:
            value = c.value
            if c.type == 'bool':
                value = 'TRUE' if value else 'FALSE'
            elif c.type in ('string', 'wstring'):
                value = json.dumps(value)
            lines.append(f'  const {IDL_BASE_TYPE[c.type]} {c.name} = {value};')
        lines.append('};')
    lines.append('@final')
    lines.append(f'struct {name}_ {{')
    members = [idl_member(f) for f in spec.fields] or ['uint8 structure_needs_at_least_one_member;']
    lines += [f'  {m}' for m in members]
    lines += ['};', '}; }; };', '#endif', '']
    return '\n'.join(lines)


def header_text(specs, hashes):
    lines = ['// Generated by ros2/tools/msg2idl.py: do not edit.',
             '// One Ros2Type<> per message: its ROS 2 name, the DDS type name of the ROS 2',
             '// conventions, the REP 2011 type hash and the idlc topic descriptor.',
             '#pragma once', '#include <cstdint>', '#include <dds/dds.h>']
    for spec in specs:
        lines.append(f'#include "{spec.base_type.pkg_name}/msg/dds_/{spec.msg_name}_.h"')
    lines += ['', 'namespace fnmpc::ros2 {', 'template <typename Message>', 'struct Ros2Type;']
    for spec in specs:
        pkg, name = spec.base_type.pkg_name, spec.msg_name
        c_name = f'{pkg}_msg_dds__{name}_'
        lines += ['template <>', f'struct Ros2Type<{c_name}> {{',
                  f'  static constexpr const char* kRosName = "{ros_name(pkg, name)}";',
                  f'  static constexpr const char* kDdsName = "{pkg}::msg::dds_::{name}_";',
                  f'  static constexpr const char* kTypeHash = "{hashes[ros_name(pkg, name)]}";',
                  f'  static const dds_topic_descriptor_t* Descriptor() {{ return &{c_name}_desc; }}',
                  '};']
        for c in spec.constants:
            if c.type in CPP_CONSTANT_TYPE:
                value = str(c.value).lower() if c.type == 'bool' else c.value
                lines.append(f'inline constexpr {CPP_CONSTANT_TYPE[c.type]} {pkg}_{name}_{c.name} = '
                             f'{value};')
    lines += ['}  // namespace fnmpc::ros2', '']
    return '\n'.join(lines)


def main(argv):
    if len(argv) < 5:
        print(__doc__, file=sys.stderr)
        return 2
    msg_root, out_dir, header = Path(argv[1]), Path(argv[2]), Path(argv[3])
    specs, files = [], {}
    for item in argv[4:]:
        pkg, _, name = item.partition('/')
        msg_file = msg_root / pkg / f'{name}.msg'
        try:
            spec = parse_message_file(pkg, str(msg_file))
        except Exception as e:  # the parser's exceptions name the problem but not the file
            raise MsgError(f'{msg_file}: {e}') from e
        specs.append(spec)
        files[ros_name(pkg, name)] = msg_file
    individual = {}
    for spec in specs:
        d = individual_description(files[ros_name(spec.base_type.pkg_name, spec.msg_name)], spec)
        individual[d['type_name']] = d
    hashes = {}
    for spec in specs:
        pkg, name = spec.base_type.pkg_name, spec.msg_name
        full = full_description(ros_name(pkg, name), individual)
        hashes[ros_name(pkg, name)] = type_hash(full)
        idl_path = out_dir / pkg / 'msg' / 'dds_' / f'{name}_.idl'
        idl_path.parent.mkdir(parents=True, exist_ok=True)
        idl_path.write_text(idl_text(spec))
        (out_dir / pkg / 'msg' / f'{name}.json').write_text(canonical_json(full) + '\n')
    header.parent.mkdir(parents=True, exist_ok=True)
    header.write_text(header_text(specs, hashes))
    return 0


if __name__ == '__main__':
    try:
        sys.exit(main(sys.argv))
    except MsgError as e:
        print(f'msg2idl: {e}', file=sys.stderr)
        sys.exit(1)
