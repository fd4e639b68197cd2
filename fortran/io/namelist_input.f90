!> Read a scene from namelist text, apply `--set GROUP.ITEM=VALUE` overrides, write the
!> resolved scene back, and print the schema: all through the item tables of
!> pymr_model_scene, one generic path for every group and item.
module pymr_io_namelist_input
  use pymr_env_kinds, only : dp, name_len
  use pymr_env_error, only : error_type, fatal_error, prefix_error, set_fault
  use pymr_model_scene, only : scene_t, unset, group_names, single_groups, repeated_groups, describe_group, &
    & group_origin, &
    & group_count, naming_item, complete_scene, item_applies
  use pymr_env_item_table, only : item_table, origin_t, set_item, given_values, value_text, suggestion, schema_line, comma_list, &
    & t_string
  use pymr_env_namelist_parse, only : group_text, item_text, token_t, parse_namelist, parse_values, group_label
  use pymr_env_text, only : itoa, lower
  use pymr_io_sha256, only : sha256_hex
  use pymr_env_text_file, only : read_text_file
  implicit none
  private
  public :: read_scene, read_scene_text, resolved_text, resolved_texts, schema_text, scene_fingerprint, &
    & text_fingerprint, item_value, canonical_address
  public :: check_removal
  public :: checkpoint_identity

  !> One --set entry: group[sel].item=values.
  type :: override_t
    character(len=name_len) :: group = '', sel = '', item = ''
    character(len=:), allocatable :: source
    type(token_t), allocatable :: values(:)
  end type override_t

contains

  !> Read `file` into `sc`, applying `overrides` ("group.item=value" or
  !> "group[name].item=value" entries, separated by newlines or ';').
  subroutine read_scene(file, overrides, sc, error)
    character(len=*), intent(in) :: file, overrides
    type(scene_t), intent(out) :: sc
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable :: text
    call read_text_file(file, text, error); if (allocated(error)) return
    call read_scene_text(text, file, overrides, sc, error)
  end subroutine read_scene

  !> Read a scene from `text`; `file` names it in messages (and is the base of its
  !> relative paths). A `draft` (a scene being built, pymr.Scene.add) may lack the groups
  !> every scene needs; its groups and items are checked as in a scene.
  subroutine read_scene_text(text, file, overrides, sc, error, draft)
    character(len=*), intent(in) :: text, file, overrides
    type(scene_t), target, intent(out) :: sc
    type(error_type), allocatable, intent(out) :: error
    logical, intent(in), optional :: draft
    type(group_text), allocatable :: groups(:)
    type(override_t), allocatable :: ovs(:)
    integer :: ng, i
    sc%file = file
    call parse_overrides(overrides, ovs, error)
    if (allocated(error)) then
      error%message = file // ': ' // error%message; return
    end if
    call parse_namelist(text, file, repeated_groups, groups, ng, error); if (allocated(error)) return
    call check_groups(file, groups(1:ng), error, draft); if (allocated(error)) return
    call allocate_records(sc, groups(1:ng))
    do i = 1, ng
      call fill_group(sc, groups(i), error); if (allocated(error)) return
    end do
    call label_single_groups(sc, groups(1:ng))
    do i = 1, size(ovs)
      call apply_override(sc, ovs(i), error); if (allocated(error)) return
    end do
    call complete_scene(sc)
  end subroutine read_scene_text

  !> Unknown groups (with the nearest known name), single groups given twice, required
  !> groups missing (but in a draft).
  subroutine check_groups(file, groups, error, draft)
    character(len=*), intent(in) :: file
    type(group_text), intent(in) :: groups(:)
    type(error_type), allocatable, intent(out) :: error
    logical, intent(in), optional :: draft
    integer :: i
    do i = 1, size(groups)
      associate(g => groups(i))
        if (index(' ' // group_names // ' ', ' ' // trim(g%name) // ' ') == 0) then
          call fatal_error(error, file // ':' // itoa(g%line) // ': &' // trim(g%name) // ': unknown group (known: ' &
            & // comma_list(group_names) // ')' // suggestion(trim(g%name), group_names, group=.true.)); return
        end if
        if (g%index > 1 .and. index(' ' // single_groups // ' ', ' ' // trim(g%name) // ' ') > 0) then
          call fatal_error(error, file // ':' // itoa(g%line) // ': &' // trim(g%name) // ': group given twice ' // &
            & '(only one is allowed)'); return
        end if
      end associate
    end do
    if (present(draft)) then
      if (draft) return
    end if
    if (.not. any(groups%name == 'scene')) then
      call fatal_error(error, file // ': &scene: missing group (it holds title, t_end, gravity)'); return
    end if
    if (.not. any(groups%name == 'integrator')) then
      call fatal_error(error, file // ': &integrator: missing group (it holds method, h_fast, h_slow, ...)'); return
    end if
    if (.not. any(groups%name == 'body')) then
      call fatal_error(error, file // ': &body: missing group (a scene needs a ground body and at least one more)')
    end if
  end subroutine check_groups

  subroutine allocate_records(sc, groups)
    type(scene_t), intent(inout) :: sc
    type(group_text), intent(in) :: groups(:)
    allocate(sc%bodies(count(groups%name == 'body')), sc%joints(count(groups%name == 'joint')))
    allocate(sc%drives(count(groups%name == 'drive')), sc%springs(count(groups%name == 'spring')))
    allocate(sc%motions(count(groups%name == 'motion')), sc%loads(count(groups%name == 'load')))
    allocate(sc%markers(count(groups%name == 'marker')), sc%forces(count(groups%name == 'force')))
    allocate(sc%controls(count(groups%name == 'control')))
    allocate(sc%moving_loads(count(groups%name == 'moving_load')), sc%sensors(count(groups%name == 'sensor')))
  end subroutine allocate_records

  !> Set the record of one group occurrence from its items, through its table.
  subroutine fill_group(sc, g, error)
    type(scene_t), target, intent(inout) :: sc
    type(group_text), intent(in) :: g
    type(error_type), allocatable, intent(out) :: error
    type(origin_t), pointer :: o
    integer :: i, j
    o => group_origin(sc, trim(g%name), g%index)
    o%file = sc%file; o%line = g%line; o%index = g%index
    o%label = group_label(g, size(g%items))
    do i = 1, size(g%items)
      associate(it => g%items(i))
        do j = 1, i - 1
          if (g%items(j)%name == it%name) then
            call fatal_error(error, sc%file // ':' // itoa(it%line) // ': ' // o%label // ': ' // trim(it%name) // &
              & ': given twice in the group (also on line ' // itoa(g%items(j)%line) // ')'); return
          end if
        end do
        call set_record_item(sc, trim(g%name), g%index, trim(it%name), it%values, &
          & sc%file // ':' // itoa(it%line) // ': ' // o%label, error)
        if (allocated(error)) then
          call name_without_equals(sc, g, it, o%label, error); return
        end if
        call o%note(trim(it%name), it%line, given_values(it%values), room=size(g%items))
      end associate
    end do
  end subroutine fill_group

  !> Set `item` of occurrence k of group `name` from its tokens, through the group's table;
  !> `where` ("file:12: &body 'gun'") prefixes errors.
  subroutine set_record_item(sc, name, k, item, values, where, error)
    type(scene_t), target, intent(inout) :: sc
    character(len=*), intent(in) :: name, item, where
    integer, intent(in) :: k
    type(token_t), intent(in) :: values(:)
    type(error_type), allocatable, intent(out) :: error
    type(item_table) :: t
    type(token_t) :: joined(1)
    call describe_group(sc, name, k, t, only=item)
    if (t%n == 0) then
      call describe_group(sc, name, k, t)
      call unknown_item(where, item, t, error); return
    end if
    if (t%items(1)%type == t_string .and. t%items(1)%count == 1 .and. size(values) > 1 .and. &
      & all(values%line == 0) .and. .not. any(values%quoted)) then
      ! a bare text of several words on the command line is one text: --set scene.title=a run
      joined(1)%text = join_words(values); joined(1)%quoted = .true.
      call set_item(t%items(1), joined, error)
    else
      call set_item(t%items(1), values, error)
    end if
    if (allocated(error)) call set_fault(error, kind='bad_value', group=name, item=item, fault=error%message)
    if (allocated(error)) call prefix_error(error, where // ': ' // item)
  end subroutine set_record_item

  !> Does occurrence k of group `name` carry the name `sel` (its naming item's value)?
  logical function selected(sc, name, k, sel)
    type(scene_t), target, intent(inout) :: sc
    character(len=*), intent(in) :: name, sel
    integer, intent(in) :: k
    type(item_table) :: t
    call describe_group(sc, name, k, t, only=naming_item(name))
    selected = trim(t%items(1)%s) == trim(sel)
  end function selected

  !> Bare words joined by one blank.
  function join_words(values) result(s)
    type(token_t), intent(in) :: values(:)
    character(len=:), allocatable :: s
    integer :: k
    s = values(1)%text
    do k = 2, size(values)
      s = s // ' ' // values(k)%text
    end do
  end function join_words

  !> A value that is the name of another item of the group most likely lost its '=':
  !> "mass 1.0" read as values of the item before. Say so, at that name's line.
  subroutine name_without_equals(sc, g, it, label, error)
    type(scene_t), target, intent(inout) :: sc
    type(group_text), intent(in) :: g
    type(item_text), intent(in) :: it
    character(len=*), intent(in) :: label
    type(error_type), allocatable, intent(inout) :: error
    type(item_table) :: t
    integer :: k
    do k = 2, size(it%values)
      if (it%values(k)%quoted) cycle
      call describe_group(sc, trim(g%name), g%index, t, only=lower(it%values(k)%text))
      if (t%n == 0) cycle
      error%message = sc%file // ':' // itoa(it%values(k)%line) // ': ' // label // ': ' // &
        & lower(it%values(k)%text) // ': expected ''='' after the item name'
      if (k < size(it%values)) error%message = error%message // ', found ''' // it%values(k + 1)%text // ''''

      return
    end do
  end subroutine name_without_equals

  !> The single groups the file does not give still get a label and the file for messages.
  subroutine label_single_groups(sc, groups)
    type(scene_t), target, intent(inout) :: sc
    type(group_text), intent(in) :: groups(:)
    type(origin_t), pointer :: o
    integer :: i, j
    character(len=16) :: name
    i = 1
    do while (i <= len(single_groups))
      j = index(single_groups(i:) // ' ', ' ') + i - 2
      name = single_groups(i:j)
      if (.not. any(groups%name == name)) then
        o => group_origin(sc, trim(name), 1)
        o%file = sc%file; o%label = '&' // trim(name)
      end if
      i = j + 2
    end do
  end subroutine label_single_groups

  !> "unknown item 'x'" with the nearest known item, and the list.
  subroutine unknown_item(where, name, t, error)
    character(len=*), intent(in) :: where, name
    type(item_table), intent(in) :: t
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable :: names
    integer :: k
    names = ''
    do k = 1, t%n
      names = names // ' ' // trim(t%items(k)%name)
    end do
    call fatal_error(error, where // ': unknown item ''' // trim(name) // ''' (known: ' // comma_list(names) // ')' &
      & // suggestion(trim(name), names))
  end subroutine unknown_item

  ! ------------------------------------------------------------------------ overrides

  !> Split the override text, one GROUP.ITEM=VALUE a line (mrsim's --set, Python's list), into
  !> entries, each parsed by the value parser of the files; a ';' is part of its line's value
  !> (a title 'a;b').
  subroutine parse_overrides(text, ovs, error)
    character(len=*), intent(in) :: text
    type(override_t), allocatable, intent(out) :: ovs(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: i0, i, n
    character(len=:), allocatable :: entry
    allocate(ovs(0))
    i0 = 1; n = len(text)
    do i = 1, n + 1
      if (i <= n) then
        if (text(i:i) /= achar(10)) cycle
      end if
      entry = trim(adjustl(text(i0:i-1)))
      i0 = i + 1
      if (len(entry) == 0) cycle
      ovs = [ovs, override_t()]
      call parse_one(entry, ovs(size(ovs)), error); if (allocated(error)) return
    end do
  end subroutine parse_overrides

  subroutine parse_one(entry, ov, error)
    character(len=*), intent(in) :: entry
    type(override_t), intent(inout) :: ov
    type(error_type), allocatable, intent(out) :: error
    integer :: eq
    ov%source = '--set ' // entry
    eq = index(entry, '=')
    if (eq == 0) then
      call fatal_error(error, ov%source // ': expected GROUP.ITEM=VALUE or GROUP[NAME].ITEM=VALUE'); return
    end if
    call parse_address(entry(1:eq-1), ov, error); if (allocated(error)) return
    call parse_values(entry(eq+1:), ov%source // ': ' // address_label(ov) // ': ' // trim(ov%item), ov%values, error)
  end subroutine parse_one

  !> GROUP.ITEM or GROUP[NAME].ITEM into ov's group, selector and item.
  subroutine parse_address(address, ov, error)
    character(len=*), intent(in) :: address
    type(override_t), intent(inout) :: ov
    type(error_type), allocatable, intent(out) :: error
    integer :: dot, lb, rb
    if (.not. allocated(ov%source)) ov%source = address
    lb = index(address, '['); rb = index(address, ']', back=.true.)
    if (lb > 0 .and. rb > lb) then
      dot = index(address(rb:), '.') + rb - 1
      if (dot < rb) dot = 0
    else
      dot = index(address, '.')
    end if
    if (dot <= 1 .or. dot == len(address)) then
      call fatal_error(error, ov%source // ': expected GROUP.ITEM=VALUE or GROUP[NAME].ITEM=VALUE'); return
    end if
    if (lb > 0 .and. rb > lb) then
      ov%group = lower(trim(adjustl(address(1:lb-1)))); ov%sel = unquoted(trim(adjustl(address(lb+1:rb-1))))
    else
      ov%group = lower(trim(adjustl(address(1:dot-1))))
    end if
    ov%item = lower(trim(adjustl(address(dot+1:))))
    if (index(' ' // group_names // ' ', ' ' // trim(ov%group) // ' ') == 0 .or. len_trim(ov%group) == 0) then
      call fatal_error(error, ov%source // ': unknown group ''' // trim(ov%group) // ''' (known: ' // &
        & comma_list(group_names) // ')' // suggestion(trim(ov%group), group_names)); return
    end if
    if (index(' ' // single_groups // ' ', ' ' // trim(ov%group) // ' ') > 0) then
      if (len_trim(ov%sel) > 0) then
        call fatal_error(error, ov%source // ': &' // trim(ov%group) // ' is not repeated: write ' // &
          & trim(ov%group) // '.' // trim(ov%item)); return
      end if
    else if (len_trim(ov%sel) == 0) then
      call fatal_error(error, ov%source // ': &' // trim(ov%group) // ' is a repeated group: name one as ' // &
        & trim(ov%group) // '[NAME].' // trim(ov%item)); return
    end if
  end subroutine parse_address

  !> A group's name as written in a selector: body[gun], or quoted as in the scene,
  !> body['gun'] or body["gun"].
  pure function unquoted(name) result(s)
    character(len=*), intent(in) :: name
    character(len=:), allocatable :: s
    integer :: n
    n = len(name)
    s = name
    if (n < 2) return
    if ((name(1:1) == '''' .or. name(1:1) == '"') .and. name(n:n) == name(1:1)) s = name(2:n-1)
  end function unquoted

  !> The one spelling of the item `address` names: GROUP.ITEM or GROUP[NAME].ITEM, group and
  !> item in lower case, the name unquoted ('Integrator.H_SLOW' and "body['bob'].mass" name
  !> integrator.h_slow and body[bob].mass). Two addresses name one item when their
  !> spellings are equal.
  subroutine canonical_address(address, text, error)
    character(len=*), intent(in) :: address
    character(len=:), allocatable, intent(out) :: text
    type(error_type), allocatable, intent(out) :: error
    type(override_t) :: ov
    call parse_address(address, ov, error); if (allocated(error)) return
    text = trim(ov%group)
    if (len_trim(ov%sel) > 0) text = text // '[' // trim(ov%sel) // ']'
    text = text // '.' // trim(ov%item)
  end subroutine canonical_address

  !> "&body 'gun'" or "&integrator" for the group an address names.
  function address_label(ov) result(s)
    type(override_t), intent(in) :: ov
    character(len=:), allocatable :: s
    s = '&' // trim(ov%group)
    if (len_trim(ov%sel) > 0) s = s // ' ''' // trim(ov%sel) // ''''
  end function address_label

  !> The value text of the item at `address` (GROUP.ITEM or GROUP[NAME].ITEM) of a read
  !> scene, as the resolved scene writes it ('' if the item holds no value). A name that
  !> several groups share (the six &motion of one joint) gives their value when they agree,
  !> and is refused when they differ: an override sets them all, a read cannot give one.
  subroutine item_value(sc, address, text, error)
    type(scene_t), target, intent(inout) :: sc
    character(len=*), intent(in) :: address
    character(len=:), allocatable, intent(out) :: text
    type(error_type), allocatable, intent(out) :: error
    type(override_t) :: ov
    type(item_table) :: t
    character(len=:), allocatable :: first, value
    integer :: k, j, k1
    call parse_address(address, ov, error); if (allocated(error)) return
    k1 = 0
    do k = 1, group_count(sc, trim(ov%group))
      if (len_trim(ov%sel) > 0) then
        if (.not. selected(sc, trim(ov%group), k, ov%sel)) cycle
      end if
      call describe_group(sc, trim(ov%group), k, t)
      j = t%find(ov%item)
      if (j == 0) then
        call unknown_item(address // ': &' // trim(ov%group), ov%item, t, error); return
      end if
      value = value_text(t%items(j))
      if (k1 == 0) then
        first = value; k1 = k
      else if (value /= first) then
        call differing_values(sc, address, ov, k1, first, k, value, error); return
      end if
    end do
    if (k1 > 0) then
      text = first; return
    end if
    call fatal_error(error, address // ': no &' // trim(ov%group) // ' group with ' // &
      & naming_item(trim(ov%group)) // ' ''' // trim(ov%sel) // '''')
  end subroutine item_value

  !> The refusal of a read whose address names groups k1 and k (and maybe more) holding
  !> other values (a and b) of its item.
  subroutine differing_values(sc, address, ov, k1, a, k, b, error)
    type(scene_t), target, intent(inout) :: sc
    character(len=*), intent(in) :: address, a, b
    type(override_t), intent(in) :: ov
    integer, intent(in) :: k1, k
    type(error_type), allocatable, intent(out) :: error
    type(origin_t), pointer :: o1, o2
    o1 => group_origin(sc, trim(ov%group), k1)
    o2 => group_origin(sc, trim(ov%group), k)
    call fatal_error(error, address // ': ' // itoa(named_count(sc, ov)) // ' &' // trim(ov%group) // &
      & ' groups have ' // naming_item(trim(ov%group)) // ' ''' // trim(ov%sel) // ''' and their ' // trim(ov%item) // &
      & ' differs (' // show(a) // ' in ' // o1%label // at_line(o1%line) // ', ' // show(b) // ' in ' // o2%label // &
      & at_line(o2%line) // '): a read gives one value (an override sets them all)')
  contains
    function show(v) result(r)
      character(len=*), intent(in) :: v
      character(len=:), allocatable :: r
      r = v
      if (len(v) == 0) r = 'none'
    end function show
    function at_line(line) result(r)
      integer, intent(in) :: line
      character(len=:), allocatable :: r
      r = ''
      if (line > 0) r = ' at line ' // itoa(line)
    end function at_line
  end subroutine differing_values

  !> How many groups the selector of ov names.
  integer function named_count(sc, ov) result(n)
    type(scene_t), target, intent(inout) :: sc
    type(override_t), intent(in) :: ov
    integer :: k
    n = 0
    do k = 1, group_count(sc, trim(ov%group))
      if (selected(sc, trim(ov%group), k, ov%sel)) n = n + 1
    end do
  end function named_count

  !> Set one override on every occurrence of its group that its selector names.
  subroutine apply_override(sc, ov, error)
    type(scene_t), target, intent(inout) :: sc
    type(override_t), intent(in) :: ov
    type(error_type), allocatable, intent(out) :: error
    type(origin_t), pointer :: o
    integer :: k, hits
    hits = 0
    do k = 1, group_count(sc, trim(ov%group))
      if (len_trim(ov%sel) > 0) then
        if (.not. selected(sc, trim(ov%group), k, ov%sel)) cycle
      end if
      o => group_origin(sc, trim(ov%group), k)
      call set_record_item(sc, trim(ov%group), k, trim(ov%item), ov%values, sc%file // ': ' // ov%source // ': ' // &
        & o%label, error)
      if (allocated(error)) return
      call o%note_set(trim(ov%item), ov%source, given_values(ov%values))
      hits = hits + 1
    end do
    if (hits == 0) call fatal_error(error, sc%file // ': ' // ov%source // ': no &' // trim(ov%group) // &
      & ' group with ' // naming_item(trim(ov%group)) // ' ''' // trim(ov%sel) // '''')
  end subroutine apply_override

  ! ------------------------------------------------------------- writing and schema

  !> The resolved scene: every group in order, every item with a value (defaults filled in,
  !> overrides applied), reals in the fewest digits that read back exactly.
  !> With `absolute_paths`, files given relative to the scene's folder are written absolute
  !> (for a copy of the scene placed elsewhere).
  function resolved_text(sc, absolute_paths, groups, omit, given) result(text)
    type(scene_t), target, intent(inout) :: sc
    logical, intent(in), optional :: absolute_paths
    !> Only these groups (blank-separated; default all).
    character(len=*), intent(in), optional :: groups
    !> Without the occurrences this address names: GROUP or GROUP[NAME] (check_removal).
    character(len=*), intent(in), optional :: omit
    !> Only the single groups the text or an override gives (a scene being built: a group
    !> not given yet can still be added).
    logical, intent(in), optional :: given
    character(len=:), allocatable :: text, relative
    logical :: want_absolute
    want_absolute = .false.
    if (present(absolute_paths)) want_absolute = absolute_paths
    if (want_absolute) then
      call put_resolved(sc, relative, text, groups, omit, given)
    else
      call put_resolved(sc, text, groups=groups, omit=omit, given=given)
    end if
  end function resolved_text

  !> The whole resolved scene in one pass, as resolved_text gives it without and with
  !> absolute paths: `text` and `absolute`.
  subroutine resolved_texts(sc, text, absolute)
    type(scene_t), target, intent(inout) :: sc
    character(len=:), allocatable, intent(out) :: text, absolute
    call put_resolved(sc, text, absolute)
  end subroutine resolved_texts

  !> resolved_text's work: `text` as written and, when present, `absolute` with the files
  !> given relative to the scene's folder written absolute.
  subroutine put_resolved(sc, text, absolute, groups, omit, given)
    type(scene_t), target, intent(inout) :: sc
    character(len=:), allocatable, intent(out) :: text
    character(len=:), allocatable, intent(out), optional :: absolute
    character(len=*), intent(in), optional :: groups, omit
    logical, intent(in), optional :: given
    type(origin_t), pointer :: o
    type(item_table) :: t
    character(len=:), allocatable :: v
    character(len=16) :: name
    integer :: i, j, k, m, n, na
    n = 0; na = 0
    allocate(character(len=4096) :: text)
    if (present(absolute)) allocate(character(len=4096) :: absolute)
    i = 1
    do while (i <= len(group_names))
      j = index(group_names(i:) // ' ', ' ') + i - 2
      name = group_names(i:j)
      i = j + 2
      if (present(groups)) then
        if (index(' ' // groups // ' ', ' ' // trim(name) // ' ') == 0) cycle
      end if
      do k = 1, group_count(sc, trim(name))
        if (present(omit)) then
          if (removed(sc, omit, trim(name), k)) cycle
        end if
        if (present(given)) then
          o => group_origin(sc, trim(name), k)
          if (given .and. o%line == 0 .and. o%n == 0) cycle
        end if
        call append_both('&' // trim(name) // new_line('a'))
        call describe_group(sc, trim(name), k, t)
        do m = 1, t%n
          if (.not. item_applies(sc, trim(name), k, t%items(m)%name)) cycle
          v = value_text(t%items(m))
          if (len(v) > 0) call append(text, n, '  ' // trim(t%items(m)%name) // ' = ' // v // new_line('a'))
          if (.not. present(absolute)) cycle
          if (t%items(m)%scene_file) v = value_text(t%items(m), sc%file)
          if (len(v) > 0) call append(absolute, na, '  ' // trim(t%items(m)%name) // ' = ' // v // new_line('a'))
        end do
        call append_both('/' // new_line('a'))
      end do
    end do
    text = text(1:n)
    if (present(absolute)) absolute = absolute(1:na)
  contains
    subroutine append_both(s)
      character(len=*), intent(in) :: s
      call append(text, n, s)
      if (present(absolute)) call append(absolute, na, s)
    end subroutine append_both
  end subroutine put_resolved

  !> Append s to buf(1:n) (n advanced), doubling buf when it is full.
  pure subroutine append(buf, n, s)
    character(len=:), allocatable, intent(inout) :: buf
    integer, intent(inout) :: n
    character(len=*), intent(in) :: s
    character(len=:), allocatable :: tmp
    if (n + len(s) > len(buf)) then
      allocate(character(len=2*(n + len(s))) :: tmp)
      tmp(1:n) = buf(1:n)
      call move_alloc(tmp, buf)
    end if
    buf(n+1:n+len(s)) = s
    n = n + len(s)
  end subroutine append

  !> Group and name of a removal's address: GROUP (a single group) or GROUP[NAME] (the
  !> occurrences of a repeated group its naming item names, as --set selects them).
  subroutine removal_address(address, group, sel)
    character(len=*), intent(in) :: address
    character(len=*), intent(out) :: group, sel
    integer :: lb, rb
    lb = index(address, '['); rb = index(address, ']', back=.true.)
    sel = ''
    if (lb > 0 .and. rb > lb) then
      group = lower(trim(adjustl(address(1:lb-1)))); sel = unquoted(trim(adjustl(address(lb+1:rb-1))))
    else
      group = lower(trim(adjustl(address)))
    end if
  end subroutine removal_address

  !> Whether occurrence k of group `name` is one that removal address `omit` names.
  logical function removed(sc, omit, name, k)
    type(scene_t), target, intent(inout) :: sc
    character(len=*), intent(in) :: omit, name
    integer, intent(in) :: k
    character(len=name_len) :: group, sel
    call removal_address(omit, group, sel)
    removed = trim(group) == name
    if (removed .and. len_trim(sel) > 0) removed = selected(sc, name, k, sel)
  end function removed

  !> A removal's address names a known group, with a name when it is repeated (and none
  !> when single), and at least one occurrence of it in the scene.
  subroutine check_removal(sc, address, error)
    type(scene_t), target, intent(inout) :: sc
    character(len=*), intent(in) :: address
    type(error_type), allocatable, intent(out) :: error
    character(len=name_len) :: group, sel
    character(len=:), allocatable :: what
    integer :: k
    call removal_address(address, group, sel)
    what = sc%file // ': remove &' // trim(group)
    if (len_trim(sel) > 0) what = what // ' ''' // trim(sel) // ''''
    if (index(' ' // group_names // ' ', ' ' // trim(group) // ' ') == 0 .or. len_trim(group) == 0) then
      call fatal_error(error, what // ': unknown group (known: ' // comma_list(group_names) // ')' // &
        & suggestion(trim(group), group_names, group=.true.)); return
    end if
    if (index(' ' // single_groups // ' ', ' ' // trim(group) // ' ') > 0) then
      if (len_trim(sel) > 0) then
        call fatal_error(error, what // ': &' // trim(group) // ' is not repeated: give no name'); return
      end if
    else if (len_trim(sel) == 0) then
      call fatal_error(error, what // ': a repeated group: give the ' // naming_item(trim(group)) // &
        & ' of the one to remove'); return
    end if
    do k = 1, group_count(sc, trim(group))
      if (removed(sc, address, trim(group), k)) return
    end do
    if (len_trim(sel) > 0) then
      call fatal_error(error, what // ': ' // naming_item(trim(group)) // ': no &' // trim(group) // &
        & ' group with ' // naming_item(trim(group)) // ' ''' // trim(sel) // '''')
      call set_fault(error, group=trim(group), item=naming_item(trim(group)), fault='no such group')
    else
      call fatal_error(error, what // ': the scene has no &' // trim(group) // ' group')
      call set_fault(error, group=trim(group), fault='no such group')
    end if
  end subroutine check_removal

  !> What a checkpoint must share with the scene that continues it: the integrator's
  !> settings (its resolved group), and the fingerprint of the model (every group but
  !> &integrator and &output, without t_end: a restart may run further or write elsewhere;
  !> and `inputs`, the digest of the files the scene reads).
  subroutine checkpoint_identity(sc, inputs, settings, model_fingerprint)
    type(scene_t), target, intent(inout) :: sc
    character(len=*), intent(in) :: inputs
    character(len=:), allocatable, intent(out) :: settings, model_fingerprint
    real(dp) :: t_end
    settings = resolved_text(sc, groups='integrator')
    t_end = sc%scene%t_end
    sc%scene%t_end = unset
    model_fingerprint = text_fingerprint(resolved_text(sc, groups=model_groups()) // inputs)
    sc%scene%t_end = t_end
  end subroutine checkpoint_identity

  !> The groups that make the model a checkpoint belongs to: all but &integrator (its
  !> settings, compared apart) and &output.
  function model_groups() result(groups)
    character(len=:), allocatable :: groups
    integer :: i, j
    groups = ''
    i = 1
    do while (i <= len(group_names))
      j = index(group_names(i:) // ' ', ' ') + i - 2
      if (group_names(i:j) /= 'integrator' .and. group_names(i:j) /= 'output') groups = groups // ' ' // group_names(i:j)
      i = j + 2
    end do
  end function model_groups

  !> The scene's fingerprint: 'sha256:' and the hex digest of its resolved text.
  function scene_fingerprint(sc) result(s)
    type(scene_t), target, intent(inout) :: sc
    character(len=:), allocatable :: s
    s = text_fingerprint(resolved_text(sc))
  end function scene_fingerprint

  !> The fingerprint of a resolved scene text (resolved_text).
  function text_fingerprint(text) result(s)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: s
    s = 'sha256:' // sha256_hex(text)
  end function text_fingerprint

  !> The groups and items of the tables, one item a line: name, type and count, default,
  !> range or choices, unit, meaning (tab-separated, groups as '&name' lines).
  function schema_text() result(text)
    character(len=:), allocatable :: text
    type(scene_t), target :: sc
    type(item_table) :: t
    character(len=16) :: name
    integer :: i, j, m
    allocate(sc%bodies(1), sc%joints(1), sc%drives(1), sc%springs(1), sc%motions(1), sc%loads(1), sc%markers(1), sc%forces(1))
    allocate(sc%controls(1))
    allocate(sc%moving_loads(1), sc%sensors(1))
    text = ''
    i = 1
    do while (i <= len(group_names))
      j = index(group_names(i:) // ' ', ' ') + i - 2
      name = group_names(i:j)
      text = text // '&' // trim(name) // new_line('a')
      call describe_group(sc, trim(name), 1, t)
      do m = 1, t%n
        text = text // schema_line(t%items(m)) // new_line('a')
      end do
      i = j + 2
    end do
  end function schema_text

end module pymr_io_namelist_input
