!> Name lookups in O(log n): an index of names sorted once (merge sort, stable), binary
!> search for a name, and the first repeated name. Scenes with 10^5 markers stay fast.
module pymr_model_names
  use pymr_env_kinds, only : name_len
  implicit none
  private
  public :: name_index

  !> Names and the permutation that sorts them.
  type :: name_index
    character(len=name_len), allocatable :: names(:)
    integer, allocatable :: perm(:)
  contains
    procedure :: build => index_build
    procedure :: find => index_find
    procedure :: duplicate => index_duplicate
  end type name_index

contains

  !> Index `names` (a copy is kept).
  subroutine index_build(self, names)
    class(name_index), intent(inout) :: self
    character(len=*), intent(in) :: names(:)
    integer, allocatable :: work(:)
    integer :: i
    self%names = names
    self%perm = [(i, i = 1, size(names))]
    allocate(work(size(names)))
    call merge_sort(self%names, self%perm, work, 1, size(names))
  end subroutine index_build

  !> Position of `name` in the indexed names (the first, if repeated), 0 if absent.
  pure integer function index_find(self, name) result(k)
    class(name_index), intent(in) :: self
    character(len=*), intent(in) :: name
    integer :: lo, hi, mid
    lo = 1; hi = size(self%perm)
    do while (lo < hi)
      mid = (lo + hi)/2
      if (llt(self%names(self%perm(mid)), name)) then
        lo = mid + 1
      else
        hi = mid
      end if
    end do
    k = 0
    if (lo <= size(self%perm)) then
      if (self%names(self%perm(lo)) == name) k = self%perm(lo)
    end if
  end function index_find

  !> The first pair (i < j, j smallest) of equal non-blank names; j = 0 if none.
  pure subroutine index_duplicate(self, i, j)
    class(name_index), intent(in) :: self
    integer, intent(out) :: i, j
    integer :: k
    i = 0; j = 0
    do k = 2, size(self%perm)
      associate(a => self%perm(k - 1), b => self%perm(k))
        if (self%names(a) /= self%names(b) .or. len_trim(self%names(b)) == 0) cycle
        if (j == 0 .or. b < j) then
          i = a; j = b
        end if
      end associate
    end do
  end subroutine index_duplicate

  !> Stable merge sort of perm(lo:hi) by names(perm(.)).
  pure recursive subroutine merge_sort(names, perm, work, lo, hi)
    character(len=*), intent(in) :: names(:)
    integer, intent(inout) :: perm(:), work(:)
    integer, intent(in) :: lo, hi
    integer :: mid, i, j, k
    if (hi - lo < 1) return
    mid = (lo + hi)/2
    call merge_sort(names, perm, work, lo, mid)
    call merge_sort(names, perm, work, mid + 1, hi)
    i = lo; j = mid + 1; k = lo
    do while (i <= mid .and. j <= hi)
      if (lle(names(perm(i)), names(perm(j)))) then
        work(k) = perm(i); i = i + 1
      else
        work(k) = perm(j); j = j + 1
      end if
      k = k + 1
    end do
    work(k:k + mid - i) = perm(i:mid); k = k + mid - i + 1
    work(k:k + hi - j) = perm(j:hi)
    perm(lo:hi) = work(lo:hi)
  end subroutine merge_sort
end module pymr_model_names
